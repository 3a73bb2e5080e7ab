"""The FMU as the sweep sees it: bytes with a checksum, unpacked once per process into a
directory of its own, with one native runner kept beside it."""

from __future__ import annotations

import atexit
import os
import hashlib
import io
import pathlib
import shutil
import tempfile
import zipfile
from typing import Any

from .errors import SpecError
from .native import NativeRunner, RunnerError

__all__ = ["Archive", "local_runner", "open_for_checks"]


class Archive:
    """An FMU's (or an SSP's) file content; what is shipped to every worker, once."""

    def __init__(self, data: bytes, name: str = "model.fmu"):
        self.data = data
        self.name = name
        self.sha256 = hashlib.sha256(data).hexdigest()

    @staticmethod
    def read(path: str | os.PathLike[str]) -> Archive:
        path = pathlib.Path(path)
        try:
            data = path.read_bytes()
        except OSError as e:
            raise FileNotFoundError(f"cannot read {path}: {e.strerror}") from None
        if not zipfile.is_zipfile(io.BytesIO(data)):
            raise ValueError(f"{path} is not an FMU or SSP (not a zip archive)")
        return Archive(data, path.name)


# Per process: checksum -> (directory, runner). A worker keeps its runner for its life.
_RUNNERS: dict[str, tuple[pathlib.Path, NativeRunner]] = {}


def local_runner(fmu: Archive) -> NativeRunner:
    """This process's runner for the FMU, unpacking and starting it on first use."""
    kept = _RUNNERS.get(fmu.sha256)
    if kept is not None:
        return kept[1]
    directory = pathlib.Path(tempfile.mkdtemp(prefix=f"fmusweep-{fmu.sha256[:12]}-"))
    try:
        with zipfile.ZipFile(io.BytesIO(fmu.data)) as archive:
            for member in archive.namelist():
                target = (directory / member).resolve()
                if not target.is_relative_to(directory.resolve()):
                    raise ValueError(f"the FMU holds a path outside its archive: {member}")
            archive.extractall(directory)
        # Executable bits are not kept by zipfile; shared libraries load without them.
        runner = NativeRunner(directory)
    except BaseException as e:
        shutil.rmtree(directory, ignore_errors=True)
        if isinstance(e, RunnerError):
            # The unpacked folder is this process's affair: the archive's own paths are named.
            raise RunnerError(str(e).replace(f"{directory}{os.sep}", "")) from None
        raise
    _RUNNERS[fmu.sha256] = (directory, runner)
    return runner


def open_for_checks(fmu: str | os.PathLike[str] | None, spec_fmu: str | os.PathLike[str] | None,
                    ) -> tuple[Archive, NativeRunner, dict[str, Any]]:
    """The FMU the caller names, else the spec's, else $FMUSWEEP_FMU: its bytes, this
    process's runner for it, and its description, for the checks before anything runs."""
    path = fmu or spec_fmu or os.environ.get("FMUSWEEP_FMU")
    if not path:
        raise SpecError("fmu", "no FMU: name one in the spec (fmu = \"…\"), give --fmu FILE "
                               "on the command line (fmu= from Python), or set FMUSWEEP_FMU")
    # What named it: the spec or the caller (fmu = …, fmu=, --fmu), or the environment.
    named_by = "fmu" if fmu or spec_fmu else "FMUSWEEP_FMU"
    try:
        target = Archive.read(path)
    except (OSError, ValueError) as e:
        raise SpecError(named_by, str(e)) from None
    # The runner reads the description (the one reader of it): an archive it cannot load,
    # of another FMI version for one, is refused naming the file that named it.
    try:
        local = local_runner(target)
    except (RunnerError, ValueError) as e:
        raise SpecError(named_by, f"{path}: {e}") from None
    return target, local, local.describe()


