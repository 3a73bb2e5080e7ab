"""The fit benchmark: a fit's model evaluations per second against the sweep's points per
second on the same scenario and outputs, serially and on 1 and 2 LocalCluster workers, at
two costs per run; the worked example's estimates; the intervals' coverage over 20 noise
seeds.

    python bench/bench_fit.py <CyclicMechanism.fmu> <output directory> [--quick]

Writes results.json and results.md. Every ratio comes from runs made side by side in this
one process; absolute times depend on the machine, which the report names.
"""

import pathlib
import sys
import tempfile
import time

import numpy as np

from bench_sweep import machine, write_results
from fmusweep import run_sweep
from fmusweep import fit
from fmusweep.fitting import FitSpec
from fmusweep.fmu import Archive, local_runner
from fmusweep.spec import Scenario

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples/fit/fit.toml"
TRUTH = {"k34": 150.0, "d34": 0.8}
MEASURED = ["omega1", "omega4"]
SIGMA = 0.05
# Four costs per run: the example's (5 s at H = 10 ms), the same at H = 1 ms (ten times
# the communication points), 60 s and 300 s at H = 1 ms; with the data's interval of each.
SCENARIOS = {"5 s, H = 10 ms": ({"stop": 5.0, "step": 0.01, "tolerance": 1e-8}, 0.02),
             "5 s, H = 1 ms": ({"stop": 5.0, "step": 0.001, "tolerance": 1e-8}, 0.02),
             "60 s, H = 1 ms": ({"stop": 60.0, "step": 0.001, "tolerance": 1e-8}, 0.1),
             "300 s, H = 1 ms": ({"stop": 300.0, "step": 0.001, "tolerance": 1e-8}, 0.5)}


def measured_csv(fmu, scenario: dict, interval: float, seed: int, path: pathlib.Path) -> pathlib.Path:
    every = round(interval / scenario["step"])
    runner = local_runner(Archive.read(fmu))
    runner.configure(Scenario.of({"scenario": scenario}).plan([], {"variables": MEASURED, "every": every}))
    [result] = runner.run(list(TRUTH), [list(TRUTH.values())])
    rows = np.array(result["series"])
    rows[:, 1:] += np.random.default_rng(seed).normal(0.0, SIGMA, size=rows[:, 1:].shape)
    np.savetxt(path, rows, delimiter=",", header="time," + ",".join(MEASURED), comments="", fmt="%.17g")
    return path


def fit_spec(fmu, scenario: dict, data: pathlib.Path, starts: int) -> dict:
    return {"fmu": str(fmu), "scenario": scenario,
            "data": {"file": str(data), "sigma": {c: SIGMA for c in MEASURED}},
            "fit": {"starts": starts, "seed": 7,
                    "parameters": {"k34": {"start": 80.0, "range": [10.0, 400.0]},
                                   "d34": {"start": 0.1, "range": [0.0, 5.0]}}}}


def timed_fit(spec, tmp, **engine) -> dict:
    out = pathlib.Path(tempfile.mkdtemp(dir=tmp))
    t0 = time.perf_counter()
    s = fit(spec, out=out / "fit", plots=False, **engine).summary
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "evaluations": s["evaluations"], "rate": s["evaluations"] / wall,
            "solving_rate": s["evaluations"] / s["solve_s"],
            "estimates": {k: v["estimate"] for k, v in s["parameters"].items()}}


def sweep_rate(fmu, scenario: dict, interval: float, points: int, tmp, **engine) -> dict:
    """Points/s of a sweep that reads what the fit reads: the two speeds at the data times."""
    spec = {"scenario": scenario,
            "design": {"kind": "grid", "parameters": {"k34": {"linspace": [100.0, 200.0, points]},
                                                      "d34": {"values": [0.8]}}},
            "outputs": {"series": {"variables": MEASURED, "interval": interval}}}
    out = pathlib.Path(tempfile.mkdtemp(dir=tmp))
    t0 = time.perf_counter()
    r = run_sweep(spec, fmu=fmu, out=out / "sweep", progress=False, plots=False, **engine).report
    wall = time.perf_counter() - t0
    return {"rate": points / wall, "after_startup": points / (wall - r.startup_s),
            "run_s": r.point_seconds / r.computed}


ENGINES = {"serial": {"serial": True}, "1 worker": {"workers": 1}, "2 workers": {"workers": 2}}


def speed(fmu, tmp, quick: bool) -> dict:
    rows = {}
    for i, (label, (scenario, interval)) in enumerate(SCENARIOS.items()):
        data = measured_csv(fmu, scenario, interval, 2026, pathlib.Path(tmp) / f"data-{i}.csv")
        points = max(40, int((100 if quick else 400) * 5 / scenario["stop"]))
        for engine, options in ENGINES.items():
            rows[f"{label} | sweep | {engine}"] = sweep_rate(fmu, scenario, interval, points, tmp, **options)
            for starts in (1, 4):
                spec = fit_spec(fmu, scenario, data, starts)
                repeats = 1 if quick else 3
                rows[f"{label} | {starts} | {engine}"] = min(
                    (timed_fit(spec, tmp, **options) for _ in range(repeats)), key=lambda r: r["wall_s"])
    return rows


def _noop(x):
    return x


def dask_round_trip(repeats: int = 100) -> float:
    """Seconds from submitting a no-op task on a 1-worker LocalCluster to its result: what
    each of a fit's batches pays on Dask besides its runs."""
    import logging
    from distributed import Client, LocalCluster
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        client.submit(_noop, -1, pure=False).result()
        t0 = time.perf_counter()
        for i in range(repeats):
            client.submit(_noop, i, pure=False).result()
        return (time.perf_counter() - t0) / repeats


def example(fmu, tmp) -> dict:
    out = pathlib.Path(tempfile.mkdtemp(dir=tmp)) / "example"
    s = fit(EXAMPLE, fmu=fmu, out=out, serial=True, plots=False).summary
    return {k: s[k] for k in ("status", "cost", "evaluations", "iterations", "parameters",
                              "correlation", "residual_rms", "warnings")}


def coverage(fmu, tmp, seeds: int) -> dict:
    spec = FitSpec.load(EXAMPLE)
    scenario = {"stop": spec.scenario.stop, "step": spec.scenario.step,
                "tolerance": spec.scenario.tolerance}
    inside, total, z = 0, 0, []
    for seed in range(seeds):
        data = measured_csv(fmu, scenario, 0.02, 10_000 + seed, pathlib.Path(tmp) / f"cover-{seed}.csv")
        s = fit(fit_spec(fmu, scenario, data, 1), out=pathlib.Path(tmp) / f"cover-{seed}",
                serial=True, plots=False).summary
        for name, true in TRUTH.items():
            p = s["parameters"][name]
            inside += p["ci95"][0] <= true <= p["ci95"][1]
            total += 1
            z.append((p["estimate"] - true) / p["stderr"])
    return {"seeds": seeds, "intervals": total, "inside": inside, "coverage": inside / total,
            "z_std": float(np.std(z))}


def report(r) -> str:
    lines = ["# Fit benchmark", "",
             f"Machine: {r['machine']}. Fits of k34 and d34 to two noisy speeds (tol 1e-8; the "
             "worked example's set-up at four costs per run), from one start or four run side "
             "by side, against a sweep of the same scenario reading the same outputs at the same "
             "times. Rates after start-up leave out starting the cluster (and, for the fit, "
             "checking the spec against the FMU). Ratios from one run; each fit the fastest of "
             "three.", "",
             "| scenario | run ms | starts | engine | evaluations | fit wall s | fit evaluations/s "
             "after start-up | sweep points/s after start-up | fit / sweep |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for key, row in r["speed"].items():
        label, starts, engine = key.split(" | ")
        if starts == "sweep":
            continue
        sweep = r["speed"][f"{label} | sweep | {engine}"]
        lines.append(f"| {label} | {1000 * sweep['run_s']:.1f} | {starts} | {engine} | "
                     f"{row['evaluations']} | {row['wall_s']:.2f} | {row['solving_rate']:,.0f} | "
                     f"{sweep['after_startup']:,.0f} | {row['solving_rate'] / sweep['after_startup']:.2f} |")
    lines += ["", f"A round trip through Dask (a no-op task on a 1-worker LocalCluster, submitted "
              f"and its result awaited): {1000 * r['round_trip_s']:.1f} ms.", "",
              "Speed-up of a fit from 1 to 2 workers (wall time):", ""]
    for label in SCENARIOS:
        for starts in (1, 4):
            one = r["speed"][f"{label} | {starts} | 1 worker"]["wall_s"]
            two = r["speed"][f"{label} | {starts} | 2 workers"]["wall_s"]
            serial = r["speed"][f"{label} | {starts} | serial"]["wall_s"]
            lines.append(f"- {label}, {starts} start(s): {one / two:.2f}× (serial in this process: "
                         f"{serial:.2f} s, 2 workers: {two:.2f} s)")
    e = r["example"]
    lines += ["", "## The worked example (examples/fit, serial)", "",
              f"Status {e['status']}, {e['iterations']} iterations of the best start, "
              f"{e['evaluations']} evaluations in all, cost {e['cost']:.2f}; truth k34 = 150, d34 = 0.8.", "",
              "| parameter | estimate | standard error | 95 % interval |", "| --- | --- | --- | --- |"]
    for name, p in e["parameters"].items():
        lines.append(f"| {name} | {p['estimate']:.6g} | {p['stderr']:.3g} | "
                     f"[{p['ci95'][0]:.6g}, {p['ci95'][1]:.6g}] |")
    lines.append("")
    lines.append(f"Correlation k34–d34: {e['correlation']['k34']['d34']:+.3f}; residual RMS: "
                 + ", ".join(f"{k}: {v:.4f}" for k, v in e["residual_rms"].items()) + " (noise σ = 0.05).")
    c = r["coverage"]
    lines += ["", f"Coverage of the 95 % intervals over {c['seeds']} noise seeds (the example's "
              f"set-up, one start): {c['inside']} of {c['intervals']} ({c['coverage']:.1%}); "
              f"the errors' spread in standard errors: {c['z_std']:.2f}.", ""]
    return "\n".join(lines)


def main():
    fmu, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    quick = "--quick" in sys.argv
    out.mkdir(parents=True, exist_ok=True)
    r = {"machine": machine(), "quick": quick}
    with tempfile.TemporaryDirectory() as tmp:
        r["round_trip_s"] = dask_round_trip()
        print("bench-fit: speed", flush=True)
        r["speed"] = speed(fmu, tmp, quick)
        print("bench-fit: the example", flush=True)
        r["example"] = example(fmu, tmp)
        print("bench-fit: coverage", flush=True)
        r["coverage"] = coverage(fmu, tmp, 5 if quick else 20)
    write_results(out, r, report(r))


if __name__ == "__main__":
    main()
