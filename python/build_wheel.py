"""Build the fmusweep wheel: the Python package with the native runner inside it.

    python python/build_wheel.py <fmu-runner binary> <output directory> [platform tag]

Standard library only (a wheel is a zip with a RECORD of hashes), so that building it
needs nothing beyond the Python that runs this. The wheel is tagged for a platform, since
the runner inside is a native program: the given tag (`manylinux_2_17_x86_64` for a runner
built against glibc 2.17), else this machine's.
"""

import base64
import hashlib
import pathlib
import re
import sys
import sysconfig
import zipfile

NAME = "fmusweep"
HERE = pathlib.Path(__file__).parent
REQUIRES = ["numpy", "pyarrow", "pandas", "dask", "distributed", "SALib", "scipy", "tqdm",
            "matplotlib"]


def version() -> str:
    text = (HERE / NAME / "__init__.py").read_text()
    return re.search(r'__version__ = "([^"]+)"', text).group(1)


def digest(data: bytes) -> str:
    return "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()


def build(runner: pathlib.Path, out_dir: pathlib.Path, platform: str | None = None) -> pathlib.Path:
    v = version()
    tag = "py3-none-" + (platform or re.sub(r"[-.]", "_", sysconfig.get_platform()))
    dist_info = f"{NAME}-{v}.dist-info"
    files = {}
    for path in sorted((HERE / NAME).rglob("*.py")):
        files[path.relative_to(HERE).as_posix()] = (path.read_bytes(), 0o644)
    files[f"{NAME}/py.typed"] = ((HERE / NAME / "py.typed").read_bytes(), 0o644)
    files[f"{NAME}/bin/fmu-runner"] = (runner.read_bytes(), 0o755)
    metadata = "\n".join(
        ["Metadata-Version: 2.1", f"Name: {NAME}", f"Version: {v}",
         "Summary: Sweeps of FMI 2.0 co-simulation FMUs at the FMU's speed, on Dask",
         "License: MIT", "Requires-Python: >=3.11"]
        + [f"Requires-Dist: {r}" for r in REQUIRES]) + "\n"
    files[f"{dist_info}/METADATA"] = (metadata.encode(), 0o644)
    wheel = f"Wheel-Version: 1.0\nGenerator: {NAME}-build\nRoot-Is-Purelib: false\nTag: {tag}\n"
    files[f"{dist_info}/WHEEL"] = (wheel.encode(), 0o644)
    entry = f"[console_scripts]\n{NAME} = {NAME}.cli:main\n"
    files[f"{dist_info}/entry_points.txt"] = (entry.encode(), 0o644)
    record = "".join(f"{name},{digest(data)},{len(data)}\n" for name, (data, _) in files.items())
    record += f"{dist_info}/RECORD,,\n"
    files[f"{dist_info}/RECORD"] = (record.encode(), 0o644)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{NAME}-{v}-{tag}.whl"
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, (data, mode) in files.items():
            info = zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0))
            info.external_attr = (0o100000 | mode) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, data)
    return target


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    print(build(pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), (sys.argv[3:] or [None])[0]))
