"""The FMU's parameter sensitivities in a fit (docs/sensitivities.md): what one run with
sensitivities costs against a plain run, by number of parameters, and a four-parameter
fit of 60 s runs with its Jacobian from the sensitivities against the same fit by
forward differences, serially and on 2 workers of one running local cluster.

    python bench/bench_fit_sensitivities.py <CyclicMechanism.fmu> <output directory> [--quick]

Writes results.json and results.md. Every ratio comes from runs made side by side in this
one process; absolute times depend on the machine, which the report names.
"""

import logging
import pathlib
import tempfile
import time

import numpy as np

from bench_sweep import arguments, write_results
from fmusweep import fit
from fmusweep.sensitivity_slots import read_offer, slot_parameter, slot_variable
from fmusweep.fmu import Archive, local_runner
from fmusweep.spec import Scenario

TRUTH = {"k12": 120.0, "k34": 150.0, "d12": 0.3, "d34": 0.8}
START = {"k12": 90.0, "k34": 110.0, "d12": 0.5, "d34": 0.5}
RANGES = {"k12": [20.0, 400.0], "k34": [20.0, 400.0], "d12": [0.0, 5.0], "d34": [0.0, 5.0]}
MEASURED = ["omega1", "omega2", "omega4"]
SIGMA = 0.05
SCENARIO = {"stop": 60.0, "step": 0.01, "tolerance": 1e-8}
INTERVAL = 0.1
# The parameters the slots follow, in order: the four fitted, and J2 for a fifth (one
# parameter may not take two slots).
FOLLOWED = ["k12", "k34", "d12", "d34", "J2"]


def run_cost(fmu, quick: bool) -> dict:
    """Wall time of one run by the fit's runner, plain and with 1, 2, 4 and 5 slots set:
    the fastest of many, and each against the plain run."""
    archive = Archive.read(fmu)
    runner = local_runner(archive)
    offer = read_offer(runner.describe())
    assert offer is not None, "the FMU offers no sensitivities"
    every = round(INTERVAL / SCENARIO["step"])
    rows = {}
    for n in (0, 1, 2, 4, 5):
        names = FOLLOWED[:n]
        slots = [slot_parameter(k + 1) for k in range(n)]
        extra = [slot_variable(k + 1, c) for k in range(n) for c in MEASURED]
        plan = Scenario.of({"scenario": SCENARIO}).plan([], {"variables": MEASURED + extra,
                                                             "every": every})
        runner.configure(plan)
        best = float("inf")
        for _ in range(5 if quick else 20):
            t0 = time.perf_counter()
            [result] = runner.run(list(TRUTH) + slots,
                                  [list(TRUTH.values()) + [float(offer.items[p]) for p in names]])
            best = min(best, time.perf_counter() - t0)
            assert result["status"] == "ok", result["message"]
        rows[n] = best
    return {"seconds": rows, "run_equivalents": {n: s / rows[0] for n, s in rows.items()}}


def measured_csv(fmu, path: pathlib.Path) -> pathlib.Path:
    runner = local_runner(Archive.read(fmu))
    every = round(INTERVAL / SCENARIO["step"])
    runner.configure(Scenario.of({"scenario": SCENARIO}).plan([], {"variables": MEASURED, "every": every}))
    [result] = runner.run(list(TRUTH), [list(TRUTH.values())])
    rows = np.array(result["series"])
    rows[:, 1:] += np.random.default_rng(2026).normal(0.0, SIGMA, size=rows[:, 1:].shape)
    np.savetxt(path, rows, delimiter=",", header="time," + ",".join(MEASURED), comments="", fmt="%.17g")
    return path


def one_fit(fmu, data: pathlib.Path, jacobian: str, tmp, **engine) -> dict:
    spec = {"fmu": str(fmu), "scenario": SCENARIO,
            "data": {"file": str(data), "sigma": {c: SIGMA for c in MEASURED}},
            "fit": {"jacobian": jacobian,
                    "parameters": {p: {"start": START[p], "range": RANGES[p]} for p in TRUTH}}}
    out = pathlib.Path(tempfile.mkdtemp(dir=tmp)) / "fit"
    t0 = time.perf_counter()
    s = fit(spec, out=out, plots=False, **engine).summary
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "solve_s": s["solve_s"], "status": s["status"],
            "evaluations": s["evaluations"], "computed": s["computed"],
            "estimates": {k: v["estimate"] for k, v in s["parameters"].items()},
            "stderr": {k: v["stderr"] for k, v in s["parameters"].items()}}


def fits(fmu, tmp, quick: bool) -> dict:
    from distributed import LocalCluster
    data = measured_csv(fmu, pathlib.Path(tmp) / "data.csv")
    one_fit(fmu, data, "differences", tmp, serial=True)  # warm up: imports, the runner
    rows = {}
    # One cluster for every fit on 2 workers, as a Dask user keeps one running: each fit's
    # wall time is then the fit's own, not the cluster's start.
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=logging.ERROR) as cluster:
        engines = {"serial": {"serial": True}, "2 workers": {"scheduler": cluster.scheduler_address}}
        for engine, options in engines.items():
            # Alternated, so that a slower stretch of a shared machine falls on both.
            found: dict[str, list] = {"sensitivities": [], "differences": []}
            for _ in range(1 if quick else 3):
                for jacobian in found:
                    found[jacobian].append(one_fit(fmu, data, jacobian, tmp, **options))
            for jacobian, runs in found.items():
                rows[f"{engine} | {jacobian}"] = min(runs, key=lambda r: r["wall_s"])
    return rows


def report(r) -> str:
    c = r["run_cost"]
    lines = ["# Sensitivities in a fit", "",
             f"Machine: {r['machine']}. Paper case 1 with k12 = 120, k34 = 150, d12 = 0.3, "
             f"d34 = 0.8, {SCENARIO['stop']:g} s at H = {SCENARIO['step']:g} s, tol "
             f"{SCENARIO['tolerance']:g}, reading {', '.join(MEASURED)} every {INTERVAL:g} s "
             "(and with slots set, their sensitivities). Ratios from one run.", "",
             "## One run", "",
             "| slots set | run ms | run-equivalents |", "| --- | --- | --- |"]
    for n, seconds in c["seconds"].items():
        lines.append(f"| {n} | {1000 * seconds:.2f} | {c['run_equivalents'][n]:.2f} |")
    lines += ["", f"A Jacobian of four parameters costs {c['run_equivalents']['4']:.2f} "
              "run-equivalents from the sensitivities (one run with four slots) against 5 by "
              "forward differences (the run and four perturbed runs).", "",
              "## A fit of k12, k34, d12 and d34", "",
              "Serially, and on 2 workers of one local Dask cluster started before the fits "
              "(its start is in no fit's wall time).", "",
              "| engine | Jacobian | status | wall s | solving s | evaluations asked / runs made |",
              "| --- | --- | --- | --- | --- | --- |"]
    for key, row in r["fits"].items():
        engine, jacobian = key.split(" | ")
        lines.append(f"| {engine} | {jacobian} | {row['status']} | {row['wall_s']:.2f} | "
                     f"{row['solve_s']:.2f} | {row['evaluations']} / {row['computed']} |")
    lines += ["", "| engine | wall time, differences / sensitivities | largest estimate difference, in standard errors |",
              "| --- | --- | --- |"]
    for engine in ("serial", "2 workers"):
        a, d = r["fits"][f"{engine} | sensitivities"], r["fits"][f"{engine} | differences"]
        gap = max(abs(a["estimates"][p] - d["estimates"][p]) / d["stderr"][p] for p in TRUTH)
        lines.append(f"| {engine}, the two Jacobians | {d['wall_s'] / a['wall_s']:.2f} | {gap:.2e} |")
    lines.append("")
    return "\n".join(lines)


def main():
    fmu, out, quick, r = arguments()
    with tempfile.TemporaryDirectory() as tmp:
        print("bench-sensitivities: one run", flush=True)
        r["run_cost"] = run_cost(fmu, quick)
        print("bench-sensitivities: fits", flush=True)
        r["fits"] = fits(fmu, tmp, quick)
    r["run_cost"] = {k: {str(n): v for n, v in d.items()} for k, d in r["run_cost"].items()}
    write_results(out, r, report(r))


if __name__ == "__main__":
    main()
