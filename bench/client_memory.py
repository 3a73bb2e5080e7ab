"""The sweep client's memory against the number of points: one grid sweep of one-second
runs on 2 workers, in a process of its own, so that its high-water mark is the sweep's.

    python bench/client_memory.py <CyclicMechanism.fmu> <points per axis>

Prints one JSON line: the points, the client's resident memory before the sweep (the
packages imported), its high-water mark over the sweep (writing points.parquet included),
and the growth per point between the two. The figures include the LocalCluster's
scheduler, which runs in the client; not its runner (a process of its own).
"""

import json
import os
import pathlib
import sys
import tempfile

import distributed  # noqa: F401  (imported before the first reading, as the sweep would)

from fmusweep import run_sweep

PAPER_LAWS = {"Mm_a0": 100.0, "Mm_a1": -20.0, "Mm_a2": -1.0, "Mr_b0": 20.0, "Mr_b1": -0.05}


def status_kib(field: str, pid: int | str = "self") -> int:
    for line in pathlib.Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0


def main() -> None:
    fmu, per_axis = sys.argv[1], int(sys.argv[2])
    spec = {"scenario": {"stop": 1.0, "step": 0.01, "tolerance": 1e-8, "parameters": PAPER_LAWS},
            "design": {"kind": "grid", "parameters": {
                "k34": {"linspace": [50.0, 400.0, per_axis]},
                "L": {"linspace": [0.6, 0.7, per_axis]}}},
            "outputs": {"metrics": {"peak_rod_force": {"variable": "rod_force",
                                                       "kind": "peak_abs"}}}}
    before = status_kib("VmRSS")
    with tempfile.TemporaryDirectory() as tmp:
        results = run_sweep(spec, fmu=fmu, out=pathlib.Path(tmp) / "out", workers=2,
                            progress=False, plots=False)
        points = results.summary.points
        peak = status_kib("VmHWM")
        written = (pathlib.Path(tmp) / "out" / "points.parquet").stat().st_size
    print(json.dumps({"points": points, "before_kib": before, "peak_kib": peak,
                      "bytes_per_point": (peak - before) * 1024 / points,
                      "points_parquet_bytes": written, "pid": os.getpid()}))


if __name__ == "__main__":
    main()
