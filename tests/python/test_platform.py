"""The packed binary loads on older Linux: it needs no glibc symbol version above 2.17
(RHEL/CentOS 7 and later). Every FMPy test runs against this same binary."""

import pathlib
import re
import subprocess
import sys

import fmpy

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
    assert exported and all(name.startswith(("fmi2", "fmi3")) for name in exported), \
        sorted(exported)[:5]


def test_the_archive_carries_every_desktop_platform(fmu_path, unzipped):
    """`cargo xtask test` packs the archive of `cargo xtask fmu --all-platforms`: FMPy
    sees the three FMI 2.0 platforms, each folder holding the one library it names."""
    assert fmpy.supported_platforms(str(fmu_path)) == ["darwin64", "linux64", "win64"]
    binaries = pathlib.Path(unzipped) / "binaries"
    found = sorted(str(p.relative_to(binaries)) for p in binaries.rglob("*") if p.is_file())
    assert found == ["darwin64/CyclicMechanism.dylib", "linux64/CyclicMechanism.so",
                     "win64/CyclicMechanism.dll"]
    # The formats, by their magic numbers: PE (MZ), universal Mach-O (0xcafebabe), ELF.
    assert (binaries / "win64/CyclicMechanism.dll").read_bytes()[:2] == b"MZ"
    assert (binaries / "darwin64/CyclicMechanism.dylib").read_bytes()[:4] == b"\xca\xfe\xba\xbe"
    assert (binaries / "linux64/CyclicMechanism.so").read_bytes()[:4] == b"\x7fELF"


def test_fmu_manipulation_toolbox_finds_the_archive_compliant(fmu_path):
    """The toolbox's checker (the FMI 2.0 schema and its semantic rules) on the packed
    multi-platform archive: exit status 0 and both checks passed."""
    tool = pathlib.Path(sys.executable).parent / "fmutool"
    done = subprocess.run([str(tool), "-input", str(fmu_path), "-check"], capture_output=True,
                          text=True, timeout=300)
    log = done.stdout + done.stderr
    assert done.returncode == 0, log
    assert "compliant with FMI-2.0" in log, log
    assert "No semantic error" in log, log
    assert "ERROR" not in log, log
