"""The fit benchmark: a fit's model evaluations per second against the sweep's points per
second on the same scenario and outputs, serially and on 1 and 2 LocalCluster workers, at
four costs per run; the worked example's estimates; the intervals' coverage over 20 noise
seeds; the two-experiment example against one of its experiments alone; and the
coverage of profile and Wald intervals over 200 noise seeds of a nonlinear case.

    python bench/bench_fit.py <CyclicMechanism.fmu> <output directory> [--quick]

Writes results.json and results.md. Every ratio comes from runs made side by side in this
one process; absolute times depend on the machine, which the report names.
"""

import pathlib
import tempfile
import time

import numpy as np

from bench_sweep import arguments, write_results
from fmusweep import run_sweep
from fmusweep import fit
from fmusweep.fitting import FitSpec
from fmusweep.fmu import Archive, local_runner
from fmusweep.spec import Scenario

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples/fit/fit.toml"
TWO_EXPERIMENTS = ROOT / "examples/fit/two_experiments.toml"
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
    r = run_sweep(spec, fmu=fmu, out=out / "sweep", progress=False, plots=False, **engine).summary
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


def two_experiments(fmu, tmp) -> dict:
    """The two-experiment example (profiles beside Wald), and its boosted experiment alone."""
    import tomllib
    spec = tomllib.loads(TWO_EXPERIMENTS.read_text())
    for e in spec["experiment"]:
        e["data"]["file"] = str(TWO_EXPERIMENTS.parent / e["data"]["file"])
    rows = {}
    for label, chosen in (("boosted alone", spec["experiment"][1:]), ("both", spec["experiment"])):
        out = pathlib.Path(tempfile.mkdtemp(dir=tmp)) / "fit"
        t0 = time.perf_counter()
        s = fit(dict(spec, experiment=chosen), fmu=fmu, out=out, serial=True, plots=False).summary
        rows[label] = {"wall_s": time.perf_counter() - t0, "evaluations": s["evaluations"],
                       "computed": s["computed"], "profile_s": s.get("profile_s"),
                       "correlation": s["correlation"]["Mm_a0"]["Mm_a1"],
                       "warnings": s["warnings"],
                       "parameters": {k: {"estimate": v["estimate"], "wald": v["wald_ci95"],
                                          "profile": v.get("profile_ci95")}
                                      for k, v in s["parameters"].items()}}
    return rows


# The profiles' coverage case: k34 from 0.3 s of the load's speed under heavy noise. The
# stiffness acts through a frequency and the record holds less than a period, so the cost
# is far from quadratic over the interval.
PROFILE_CASE = {"scenario": {"stop": 0.3, "step": 0.01, "tolerance": 1e-8}, "sigma": 4.0,
                "k34": 150.0, "start": 100.0, "range": [1.0, 3000.0]}


def profile_coverage(fmu, tmp, seeds: int) -> dict:
    case = PROFILE_CASE
    runner = local_runner(Archive.read(fmu))
    runner.configure(Scenario.of({"scenario": case["scenario"]}).plan([], {"variables": ["omega4"], "every": 1}))
    [truth] = runner.run(["k34"], [[case["k34"]]])
    rows = np.array(truth["series"])
    counts = {"profile": 0, "wald": 0, "open_below": 0, "open_above": 0, "lopsided": 0}
    t0 = time.perf_counter()
    for seed in range(seeds):
        noisy = rows.copy()
        noisy[:, 1:] += np.random.default_rng(20_000 + seed).normal(0.0, case["sigma"], size=noisy[:, 1:].shape)
        path = pathlib.Path(tmp) / f"profile-{seed}.csv"
        np.savetxt(path, noisy, delimiter=",", header="time,omega4", comments="", fmt="%.17g")
        spec = {"fmu": str(fmu), "scenario": case["scenario"],
                "data": {"file": str(path), "sigma": {"omega4": case["sigma"]}},
                "fit": {"intervals": "both",
                        "parameters": {"k34": {"start": case["start"], "range": case["range"]}}}}
        p = fit(spec, out=pathlib.Path(tmp) / f"profile-{seed}", serial=True, plots=False).summary["parameters"]["k34"]
        low, high = p["profile_ci95"]
        counts["open_below"] += low is None
        counts["open_above"] += high is None
        low = -np.inf if low is None else low
        high = np.inf if high is None else high
        counts["profile"] += low <= case["k34"] <= high
        counts["wald"] += p["wald_ci95"][0] <= case["k34"] <= p["wald_ci95"][1]
        counts["lopsided"] += high - p["estimate"] > 1.2 * (p["estimate"] - low)
    return {"seeds": seeds, **counts, "seconds_per_fit": (time.perf_counter() - t0) / seeds}


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
    lines += _summary_lines(r["speed"])
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
    lines += _two_experiments_report(r["two_experiments"]) + _profile_report(r["profile_coverage"])
    return "\n".join(lines)


def _summary_lines(speed: dict) -> list[str]:
    """The table's ranges the documents quote: the serial fit against the sweep for the
    costly runs (the 60 s and 300 s scenarios) and the cheap ones (5 s), and a cheap fit's
    wall time serially and on 2 workers."""
    def rows(engine, costly):
        for key, row in speed.items():
            label, starts, kind = key.split(" | ")
            if starts == "sweep" or kind != engine or label.startswith("5 s") == costly:
                continue
            yield row, speed[f"{label} | sweep | {engine}"]

    def span(values, digits):
        values = list(values)
        return f"{min(values):.{digits}f}–{max(values):.{digits}f}" if values else "—"

    return ["",
            "Serially, fit / sweep for the 60 s and 300 s runs: "
            f"{span((r['solving_rate'] / s['after_startup'] for r, s in rows('serial', True)), 2)}; "
            "for the 5 s runs: "
            f"{span((r['solving_rate'] / s['after_startup'] for r, s in rows('serial', False)), 2)}.",
            "",
            "A fit's wall time for the 5 s runs: serially "
            f"{span((r['wall_s'] for r, _ in rows('serial', False)), 2)} s, on 2 workers "
            f"{span((r['wall_s'] for r, _ in rows('2 workers', False)), 2)} s."]


def _two_experiments_report(t: dict) -> list[str]:
    lines = ["## Two experiments (examples/fit/two_experiments.toml, serial)", "",
             "The motor law's Mm_a0 and Mm_a1 from the braked and the boosted run, each run's "
             "starting speed omega1_0 fitted for it alone; truth Mm_a0 = 100, Mm_a1 = -20, "
             "omega1_0 = 0.5 (braked) and 5.0 (boosted). Wald and profile intervals side by side.", "",
             "| experiments | correlation Mm_a0–Mm_a1 | runs asked / made | wall s (profiles) | flagged |",
             "| --- | --- | --- | --- | --- |"]
    for label, row in t.items():
        flagged = "yes" if any("cannot be told apart" in w for w in row["warnings"]) else "no"
        lines.append(f"| {label} | {row['correlation']:+.4f} | {row['evaluations']} / {row['computed']} | "
                     f"{row['wall_s']:.2f} ({row['profile_s']:.2f}) | {flagged} |")
    lines += ["", "| experiments | parameter | estimate | Wald 95 % | profile 95 % | Wald width / estimate |",
              "| --- | --- | --- | --- | --- | --- |"]
    for label, row in t.items():
        for name, p in row["parameters"].items():
            wald, profile = p["wald"], p["profile"]
            width = (wald[1] - wald[0]) / abs(p["estimate"])
            lines.append(f"| {label} | {name} | {p['estimate']:.6g} | [{wald[0]:.6g}, {wald[1]:.6g}] | "
                         f"[{_bound(profile[0])}, {_bound(profile[1])}] | {width:.2%} |")
    return lines + [""]


def _bound(x) -> str:
    return "open" if x is None else f"{x:.6g}"


def _profile_report(c: dict) -> list[str]:
    case = PROFILE_CASE
    return ["## Profile intervals where the model is nonlinear", "",
            f"k34 (truth {case['k34']:g}) from {case['scenario']['stop']} s of omega4 with noise "
            f"σ = {case['sigma']} rad/s, range {case['range']}, over {c['seeds']} seeds: the 95 % "
            f"profile intervals held the truth in {c['profile']} of {c['seeds']} cases "
            f"({c['profile'] / c['seeds']:.1%}), the Wald intervals in {c['wald']} "
            f"({c['wald'] / c['seeds']:.1%}). {c['lopsided']} profile intervals reach more than "
            f"1.2 times further above the estimate than below it; {c['open_above']} are open above "
            f"(no stiffness up to the range's end is excluded) and {c['open_below']} below. "
            f"{c['seconds_per_fit']:.2f} s per fit with its profile.", ""]


def main():
    fmu, out, quick, r = arguments()
    with tempfile.TemporaryDirectory() as tmp:
        r["round_trip_s"] = dask_round_trip()
        print("bench-fit: speed", flush=True)
        r["speed"] = speed(fmu, tmp, quick)
        print("bench-fit: the example", flush=True)
        r["example"] = example(fmu, tmp)
        print("bench-fit: coverage", flush=True)
        r["coverage"] = coverage(fmu, tmp, 5 if quick else 20)
        print("bench-fit: two experiments", flush=True)
        r["two_experiments"] = two_experiments(fmu, tmp)
        print("bench-fit: profile coverage", flush=True)
        r["profile_coverage"] = profile_coverage(fmu, tmp, 20 if quick else 200)
    write_results(out, r, report(r))


if __name__ == "__main__":
    main()
