"""The packed binary loads on older Linux: it needs no glibc symbol version above 2.17
(RHEL/CentOS 7 and later). Every FMPy test runs against this same binary."""

import pathlib
import re
import subprocess

BASELINE = (2, 17)


def test_packed_binary_needs_glibc_2_17_at_most(unzipped):
    library = pathlib.Path(unzipped) / "binaries/linux64/CyclicMechanism.so"
    symbols = subprocess.run(["objdump", "-T", str(library)], check=True, capture_output=True,
                             text=True).stdout
    versions = {tuple(int(p) for p in v.split(".")[:2])
                for v in re.findall(r"GLIBC_([0-9]+\.[0-9]+(?:\.[0-9]+)?)", symbols)}
    assert versions, "no versioned glibc symbol found: is this the right binary?"
    assert max(versions) <= BASELINE, sorted(versions)
    # The exports are exactly the FMI functions (and nothing of Rust's runtime).
    exported = {line.split()[-1] for line in symbols.splitlines()
                if " .text" in line and " g " in line and "DF" in line}
    assert exported and all(name.startswith("fmi2") for name in exported), sorted(exported)[:5]
