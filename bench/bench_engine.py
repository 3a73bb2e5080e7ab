"""The engine choice against both engines, example by example: each sweep of
examples/sweeps run serially, on a LocalCluster of one worker per core, and with no engine
named (the choice fmusweep makes after its first points), one after another in this
process; and the disk estimate of sweeps with series against what they wrote.

    python bench/bench_engine.py <CyclicMechanism.fmu> <output directory> [--quick]

Each run is the whole call a user makes (checks, calibration, cluster start-up, Parquet,
no plots), the fastest of two (one with --quick). Writes results.json and results.md, and
docs/bench/engine.md (not with --quick).
"""

import os
import pathlib
import tempfile
import time
import warnings

from bench_sweep import arguments, write_results
from fmusweep import run_sweep
from fmusweep.spec import Spec
from fmusweep.sweep import written_bytes

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples/sweeps"
# The SSP example needs the SSP file `cargo xtask sweep` packs; the others only the FMUs.
NEEDS = {"coupled_motor_ssp.toml": ROOT / "target/fmu/MotorDrivenMechanism.ssp"}


def timed(spec: pathlib.Path, repeats: int, **engine) -> tuple[float, str, float]:
    """The fastest wall time of the sweep, the engine it ran on and why, and the cluster's
    start-up (0 serially)."""
    best, said, startup = float("inf"), "", 0.0
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as out, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            results = run_sweep(spec, out=pathlib.Path(out) / "r", progress=False, plots=False,
                                **engine)
            wall = time.perf_counter() - t0
        summary = results.summary
        assert summary is not None
        if wall < best:
            best = wall
            said = summary.engine if summary.engine_choice == "as asked" else summary.engine_choice
            startup = summary.startup_s
    return best, said, startup


def engines(repeats: int) -> list[dict]:
    rows = []
    for spec in sorted(EXAMPLES.glob("*.toml")):
        needed = NEEDS.get(spec.name)
        if needed is not None and not needed.exists():
            continue
        points = len(Spec.load(spec).points)
        serial, _, _ = timed(spec, repeats, serial=True)
        cluster, _, startup = timed(spec, repeats, workers=os.cpu_count())
        auto, chose, _ = timed(spec, repeats)
        rows.append({"example": spec.name, "points": points, "serial_s": serial,
                     "cluster_s": cluster, "cluster_startup_s": startup, "auto_s": auto,
                     "chose": chose})
        print(rows[-1], flush=True)
    return rows


def disk(fmu: pathlib.Path) -> list[dict]:
    """Sweeps with series: the estimate before the run against the bytes written."""
    rows = []
    for variables, stop, points in ((["omega1"], 2.0, 40), (["omega1", "omega2", "rod_force"],
                                                            2.0, 40),
                                    (["rod_force"], 10.0, 100)):
        spec = {"scenario": {"stop": stop, "step": 0.01, "tolerance": 1e-6,
                             "parameters": {"Mm_a0": 100.0, "Mm_a1": -20.0, "Mm_a2": -1.0,
                                            "Mr_b0": 20.0, "Mr_b1": -0.05}},
                "design": {"kind": "grid",
                           "parameters": {"k34": {"linspace": [50.0, 150.0, points]}}},
                "outputs": {"metrics": {"peak": {"variable": "rod_force", "kind": "max"}},
                            "series": {"variables": variables}}}
        with tempfile.TemporaryDirectory() as out:
            results = run_sweep(spec, fmu=fmu, out=pathlib.Path(out) / "r", serial=True,
                                progress=False, plots=False)
            written = sum(p.stat().st_size for p in (results.out / "points").glob("*")) + sum(
                p.stat().st_size for p in (results.out / "series").glob("*"))
        estimate, values = written_bytes(Spec.load(spec), points)
        rows.append({"variables": len(variables), "stop": stop, "points": points,
                     "values": values, "estimate_bytes": estimate, "written_bytes": written})
    return rows


def report(r: dict) -> str:
    lines = ["# The engine choice and the disk estimate", "",
             f"Machine: {r['machine']}. Each example of examples/sweeps run whole (checks, "
             "first points, cluster start-up, Parquet; no plots), serially, on a LocalCluster "
             f"of {os.cpu_count()} workers, and with no engine named; the fastest of "
             f"{r['repeats']} runs each. Written by `cargo xtask bench-engine`.", "",
             "| example | points | serial s | LocalCluster s (its start-up) | no engine named s "
             "| chosen | of the faster |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for row in r["engines"]:
        best = min(row["serial_s"], row["cluster_s"])
        chose = "serial" if row["chose"].startswith("serial") else "LocalCluster"
        lines.append(f"| {row['example']} | {row['points']:,} | {row['serial_s']:.2f} | "
                     f"{row['cluster_s']:.2f} ({row['cluster_startup_s']:.2f}) | "
                     f"{row['auto_s']:.2f} | {chose} | {row['auto_s'] / best:.2f}× |")
    lines += ["", "The disk estimate a sweep with series is checked against before it starts "
                  "(refused beyond the free space, said beyond 1 GB), against what such sweeps "
                  "wrote (points.parquet and the series):", "",
              "| variables | stop s | points | series values | estimate bytes | written bytes "
              "| estimate / written |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for row in r["disk"]:
        lines.append(f"| {row['variables']} | {row['stop']:g} | {row['points']} | "
                     f"{row['values']:,} | {row['estimate_bytes']:,} | {row['written_bytes']:,} "
                     f"| {row['estimate_bytes'] / row['written_bytes']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    fmu, out, quick, r = arguments()
    os.environ["FMUSWEEP_FMU"] = str(fmu)  # the examples that name no FMU run the packed one
    r["repeats"] = 1 if quick else 2
    r["engines"] = engines(r["repeats"])
    r["disk"] = disk(fmu)
    text = report(r)
    write_results(out, r, text)
    if not quick:
        (ROOT / "docs/bench/engine.md").write_text(text)


if __name__ == "__main__":
    main()
