"""Work-precision study, driven by `cargo xtask bench`:

    python bench/bench.py reference <output directory> [--quick]
    python bench/bench.py <harness.json> <CyclicMechanism.fmu> <output directory> [--quick]

The first writes the independent reference at every communication point of the finest
grid (for the harness's error at every point); the second
takes the Rust harness's timings and sampled states (the FMU through its C ABI, and the
Rust ODE crates), adds scipy's solve_ivp methods on the same equations and FMPy's wall
time for the same FMU runs, computes errors against a reference at rtol 1e-13 (the
independent formulation of tests/python/reference.py), and writes results.json,
results.md and work_precision.png.
"""

import hashlib
import json
import math
import pathlib
import platform
import sys
import time

import matplotlib

matplotlib.use("Agg")
import fmpy  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests/python"))
import reference  # noqa: E402

SCENARIOS = {
    "case1": dict(stop=10.0, values=dict(reference.PAPER_LAWS)),
    "free": dict(stop=100.0, values=dict(reference.FREE_RUN)),
}
SCIPY_METHODS = ["RK45", "DOP853", "LSODA", "Radau"]
SCIPY_BUDGET = 20.0  # seconds for one run; tighter tolerances are skipped after that


def spec_rhs(p):
    """docs/model.md §2's orthogonal-complement right-hand side in plain Python: what a Python
    user writes (scalar math, no arrays inside)."""
    J1, J2, J3, J4 = p.J
    l, l2, l3 = p.l, p.l2, p.l3
    laws = (p.Mm_a0, p.Mm_a1, p.Mm_a2, p.Mr_b0, p.Mr_b1) if p.builtin_laws else (0.0,) * 5
    # Named apart from the solve's own r1, r2 below.
    motor0, motor1, motor2, load0, load1 = laws

    def rhs(t, y):
        phi1, phi2, phi3, phi4, w1, w2, w3, w4 = y
        s2, c2, s3, c3 = math.sin(phi2), math.cos(phi2), math.sin(phi3), math.cos(phi3)
        s23, c23 = math.sin(phi2 - phi3), math.cos(phi2 - phi3)
        b1 = l2 * (l * s2 + l3 * s23)
        c1 = l3 * (l2 * s23 + l * s3)
        b1d = l2 * (l * c2 * w2 + l3 * c23 * (w2 - w3))
        c1d = l3 * (l2 * c23 * (w2 - w3) + l * c3 * w3)
        motor = p.M_m + motor0 + motor1 * w1 + motor2 * w1 * w1
        load = p.M_r + load0 + load1 * w1
        s12 = p.k12 * (phi2 - phi1) + p.d12 * (w2 - w1)
        s34 = p.k34 * (phi3 - phi4) + p.d34 * (w3 - w4)
        q1, q2, q3, q4 = motor + s12, -s12, -s34, s34 - load - p.c4 * w4
        r1 = c1 * q2 + b1 * q3
        r2 = -(b1d * w2 - c1d * w3)
        det = -(c1 * c1 * J2 + b1 * b1 * J3)
        return [w1, w2, w3, w4, q1 / J1, (-c1 * r1 - b1 * J3 * r2) / det,
                (c1 * J2 * r2 - b1 * r1) / det, q4 / J4]

    return rhs


def check_spec_rhs(p, y):
    """spec_rhs against the reference's formulation at state y: a slip in the scipy
    baseline's equations must stop the benchmark, not bend its figures."""
    ours, theirs = np.array(spec_rhs(p)(0.0, y)), reference.rhs(0.0, y, p)
    gap = float(np.abs(ours - theirs).max() / max(1.0, np.abs(theirs).max()))
    if not gap <= 1e-9:
        raise ValueError(f"bench.py's spec_rhs differs from reference.rhs by {gap:.3g} (relative)")


def sample_times(stop, samples):
    return stop * np.arange(1, samples + 1) / samples


def reference_step(quick):
    """The finest communication step of the study: the reference is written at its grid."""
    return 1e-3 if quick else 1e-4


def write_references(out, quick):
    """The independent reference (rtol 1e-13) at every communication point of the finest
    grid, for the harness: little-endian f64, the step first, then 8 states per point."""
    out.mkdir(parents=True, exist_ok=True)
    step = reference_step(quick)
    for name, s in SCENARIOS.items():
        path, tag = out / f"reference_{name}.f64", out / f"reference_{name}.json"
        key = dict(step=step, stop=s["stop"], values=s["values"],
                   source=hash_of(pathlib.Path(reference.__file__)))
        if path.exists() and tag.exists() and json.loads(tag.read_text()) == key:
            continue
        start = time.perf_counter()
        times = np.arange(round(s["stop"] / step) + 1) * step
        states = reference.solve(reference.Params(**s["values"]), times, rtol=1e-13)
        path.write_bytes(np.concatenate([[step], states.ravel()]).astype("<f8").tobytes())
        tag.write_text(json.dumps(key))
        print(f"reference {name}: {len(times)} points in {time.perf_counter() - start:.1f} s", flush=True)


def hash_of(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def reference_states(out, samples):
    """The reference at the harness's evenly spaced sample points (from the written grid)."""
    states = {}
    for name, s in SCENARIOS.items():
        values = np.frombuffer((out / f"reference_{name}.f64").read_bytes(), dtype="<f8")
        step, grid = values[0], values[1:].reshape(-1, 8)
        stride = round(s["stop"] / samples / step)
        states[name] = grid[stride::stride][:samples]
    return states


def errors(states, ref):
    """Final-time max error, RMS over the samples, and the final error in units of each
    component's scale (max(1, max |y_i|)). A run that did not finish (a peer whose states
    went non-finite, kept as null) has an infinite error: it is never the accurate one."""
    states = np.asarray(states, dtype=float)
    diff = np.nan_to_num(np.abs(states - ref), nan=np.inf)
    scale = np.maximum(1.0, np.abs(ref).max(axis=0))
    return float(diff[-1].max()), float(np.sqrt(np.mean(diff ** 2))), float((diff[-1] / scale).max())


def run_scipy(samples, refs, quick):
    rows = []
    tolerances = [1e-4, 1e-8] if quick else [10.0 ** -e for e in range(3, 13)]
    for name, s in SCENARIOS.items():
        p = reference.Params(**s["values"])
        rhs, y0 = spec_rhs(p), reference.initial_state(p)
        check_spec_rhs(p, y0)
        t_eval = sample_times(s["stop"], samples)
        for method in SCIPY_METHODS:
            for tol in tolerances:
                best, runs, sol = math.inf, 0, None
                while runs < 3 and (runs == 0 or best * (runs + 1) < SCIPY_BUDGET):
                    start = time.perf_counter()
                    sol = solve_ivp(rhs, (0.0, s["stop"]), y0, method=method, t_eval=t_eval, rtol=tol, atol=tol)
                    best, runs = min(best, time.perf_counter() - start), runs + 1
                if not sol.success or sol.y.shape[1] != samples:
                    rows.append(dict(method=f"scipy_{method}", scenario=name, tol=tol, failed=sol.message))
                    continue
                final, rms, scaled = errors(sol.y.T, refs[name])
                rows.append(dict(method=f"scipy_{method}", scenario=name, H=None, tol=tol, seconds=best, runs=runs,
                                 n_rhs=int(sol.nfev), final_error=final, rms_error=rms, scaled_error=scaled))
                print(f"scipy {method:6} {name} tol={tol:.0e}: {best:.3f} s, error {final:.1e}", flush=True)
                if best > SCIPY_BUDGET / 2:
                    break
    return rows


def run_fmpy(fmu, quick):
    """FMPy's wall time for some of the harness's FMU configurations (case 1)."""
    rows = []
    unzipped = fmpy.extract(str(fmu))
    values = SCENARIOS["case1"]["values"]
    for h in ([1e-3] if quick else [1e-3, 1e-2]):
        for tol in ([1e-8] if quick else [1e-4, 1e-6, 1e-8, 1e-10]):
            best = math.inf
            for _ in range(3):
                start = time.perf_counter()
                fmpy.simulate_fmu(unzipped, start_values=values, stop_time=10.0, output_interval=h,
                                  relative_tolerance=tol)
                best = min(best, time.perf_counter() - start)
            rows.append(dict(scenario="case1", H=h, tol=tol, fmpy_seconds=best))
            print(f"FMPy case1 H={h:.0e} tol={tol:.0e}: {best:.3f} s", flush=True)
    return rows


def fastest_at_least_as_accurate(rows, scenario, error, prefix, h=None):
    """The fastest run of a method family with final error ≤ `error` (same H if given)."""
    candidates = [r for r in rows if r["method"].startswith(prefix) and r["scenario"] == scenario
                  and "failed" not in r and r["final_error"] <= error and (h is None or r["H"] == h)]
    return min(candidates, key=lambda r: r["seconds"], default=None)


def slope(tols, errs):
    x, y = np.log10(tols), np.log10(errs)
    return float(np.polyfit(x, y, 1)[0])


def main(harness_json, fmu, out, quick):
    out.mkdir(parents=True, exist_ok=True)
    harness = json.loads(pathlib.Path(harness_json).read_text())
    samples = harness["samples"]
    refs = reference_states(out, samples)
    rows = []
    for r in harness["results"]:
        final, rms, scaled = errors(r.pop("states"), refs[r["scenario"]])
        rows.append(dict(r, final_error=final, rms_error=rms, scaled_error=scaled))
    rows += run_scipy(samples, refs, quick)
    fmpy_rows = run_fmpy(fmu, quick)

    fmu_rows = [r for r in rows if r["method"] == "fmu"]
    comparisons = []
    for r in fmu_rows:
        scipy = fastest_at_least_as_accurate(rows, r["scenario"], r["final_error"], "scipy_")
        crate = fastest_at_least_as_accurate(rows, r["scenario"], r["final_error"], "ode_solvers", r["H"])
        diffsol = fastest_at_least_as_accurate(rows, r["scenario"], r["final_error"], "diffsol", r["H"])
        crates = [c for c in (crate, diffsol) if c is not None]
        best_crate = min(crates, key=lambda c: c["seconds"], default=None)
        comparisons.append(dict(
            scenario=r["scenario"], H=r["H"], tol=r["tol"], fmu_seconds=r["seconds"], fmu_error=r["final_error"],
            scipy_method=scipy and scipy["method"], scipy_ratio=scipy and scipy["seconds"] / r["seconds"],
            crate_method=best_crate and best_crate["method"],
            crate_ratio=best_crate and best_crate["seconds"] / r["seconds"]))
    for f in fmpy_rows:
        match = next(r for r in fmu_rows if r["scenario"] == f["scenario"] and r["H"] == f["H"] and r["tol"] == f["tol"])
        f["fmu_share"] = match["seconds"] / f["fmpy_seconds"]

    proportionality = {}
    for name in SCENARIOS:
        for h in sorted({r["H"] for r in fmu_rows}):
            pts = [(r["tol"], r["scaled_error"]) for r in fmu_rows
                   if r["scenario"] == name and r["H"] == h and r["tol"] >= 1e-10]
            if len(pts) >= 2:
                tols, errs = zip(*sorted(pts))
                proportionality[f"{name} H={h:g}"] = dict(
                    slope=slope(tols, errs), worst_error_over_tol=max(e / t for t, e in pts))

    per_evaluation = {}
    for r in rows:
        if "failed" in r or not r.get("n_rhs"):
            continue
        key = r["method"] if r.get("H") is None else f"{r['method']} H={r['H']:g}"
        per_evaluation.setdefault(key, []).append(r["seconds"] / r["n_rhs"])
    per_evaluation = {k: float(np.median(v)) for k, v in sorted(per_evaluation.items())}
    warm = []
    for tol in sorted({r["tol"] for r in fmu_rows}, reverse=True):
        n = {r["H"]: r["n_rhs"] for r in fmu_rows if r["scenario"] == "case1" and r["tol"] == tol}
        if 1e-3 in n and 0.1 in n:
            warm.append(dict(tol=tol, n_rhs_h_1e_3=n[1e-3], n_rhs_h_0_1=n[0.1], ratio=n[1e-3] / n[0.1]))

    promise = tolerance_promise(fmu_rows)
    at_every_point = point_comparisons(rows, fmu_rows)
    floor = distance_from_floor(fmu_rows, harness.get("c_ns_per_rhs"))

    from bench_sweep import built_from, host
    machine = dict(host=host(), built_from=built_from(), python=platform.python_version())
    summary = dict(machine=machine, ns_per_rhs=harness["ns_per_rhs"], c_ns_per_rhs=harness.get("c_ns_per_rhs"),
                   proportionality=proportionality,
                   promise=promise, at_every_point=at_every_point, floor=floor,
                   compiled_targets=compiled_targets(at_every_point),
                   comparisons=comparisons, fmpy=fmpy_rows,
                   seconds_per_evaluation=per_evaluation, warm_restarts=warm, stiff=harness.get("stiff", []), results=rows)
    (out / "results.json").write_text(json.dumps(summary, indent=1))
    (out / "results.md").write_text(markdown(summary))
    plot(rows, out / "work_precision.png")
    print((out / "results.md").read_text())


PROMISE_TOLERANCES = [10.0 ** -e for e in range(3, 11)]


def tolerance_promise(fmu_rows):
    """The FMU's worst error over every communication point, in units of tol, per scenario,
    H and tol (the promise: ≤ 10 for tol 1e-3…1e-10)."""
    table = {}
    for r in fmu_rows:
        if r.get("max_point_error") is not None:
            table.setdefault(r["scenario"], {}).setdefault(r["H"], {})[r["tol"]] = r["max_point_error"] / r["tol"]
    worst = max((v for sc in table.values() for h in sc.values() for t, v in h.items()
                 if any(math.isclose(t, p) for p in PROMISE_TOLERANCES)), default=None)
    return dict(table={sc: {str(h): {f"{t:.0e}": v for t, v in row.items()} for h, row in hs.items()}
                       for sc, hs in table.items()}, worst=worst)


def distance_from_floor(fmu_rows, c_ns):
    """The FMU's time against n_rhs × the bare compiled right-hand side (the floor); the
    targets: ≤ 1.6 at H = 0.1, ≤ 2 at H = 0.01."""
    if not c_ns:
        return []
    return [dict(scenario=r["scenario"], H=r["H"], tol=r["tol"], ratio=r["seconds"] / (r["n_rhs"] * c_ns * 1e-9))
            for r in fmu_rows if r.get("n_rhs")]


# Ratio targets at equal error at every point, tol ≤ 1e-6 (peer time / FMU time).
COMPILED_TARGETS = {"hairer_dop853": 1.3, "lsoda": 2.0}


def compiled_targets(at_every_point):
    """Per peer with a target, scenario and H: the smallest ratio at tol ≤ 1e-6, and at
    how many tolerances the target is met."""
    out = []
    for peer, target in COMPILED_TARGETS.items():
        for key in sorted({(e["scenario"], e["H"]) for e in at_every_point}):
            ratios = [e["peers"].get(peer) for e in at_every_point
                      if (e["scenario"], e["H"]) == key and e["tol"] <= 1e-6 * (1 + 1e-9)]
            known = [r for r in ratios if r is not None]
            if known:
                out.append(dict(peer=peer, scenario=key[0], H=key[1], target=target, worst=min(known),
                                met=sum(r >= target for r in known), of=len(known)))
    return out


def point_comparisons(rows, fmu_rows):
    """Against each peer at the same H: the fastest of its runs whose error at every
    communication point is at most the FMU's; ratio = peer time / FMU time."""
    peers = sorted({r["method"] for r in rows if r.get("max_point_error") is not None} - {"fmu"})
    out = []
    for r in fmu_rows:
        if r.get("max_point_error") is None:
            continue
        entry = dict(scenario=r["scenario"], H=r["H"], tol=r["tol"], fmu_seconds=r["seconds"],
                     fmu_point_error=r["max_point_error"], fmu_n_rhs=r["n_rhs"], peers={})
        for peer in peers:
            runs = [p for p in rows if p["method"] == peer and p["scenario"] == r["scenario"] and p.get("H") == r["H"]
                    and p.get("max_point_error") is not None and p["max_point_error"] <= r["max_point_error"]]
            best = min(runs, key=lambda p: p["seconds"], default=None)
            entry["peers"][peer] = best and best["seconds"] / r["seconds"]
        out.append(entry)
    return out


def fmt_ratio(value, method):
    return "—" if value is None else f"{value:,.0f}× ({method.replace('scipy_', '')})" if value >= 10 \
        else f"{value:.1f}× ({method})"


def by_step(comparisons):
    """Per communication step: the range of each ratio and how many comparisons meet the target."""
    rows = []
    for h in sorted({c["H"] for c in comparisons}):
        row = dict(H=h)
        for peer, target in (("scipy", 300.0), ("crate", 3.0)):
            ratios = [c[f"{peer}_ratio"] for c in comparisons if c["H"] == h and c[f"{peer}_ratio"] is not None]
            row[peer] = f"{min(ratios):,.1f}–{max(ratios):,.1f}×" if ratios else "—"
            row[f"{peer}_met"] = f"{sum(r >= target for r in ratios)} of {len(ratios)}"
        rows.append(row)
    return rows


def at_every_point_lines(at_every_point):
    """The table of ratios against each peer at equal error at every communication point."""
    if not at_every_point:
        return []
    peers = sorted({p for e in at_every_point for p in e["peers"]})
    lines = ["", "Against each peer at equal error at every communication point (the fastest peer run whose worst "
             "error over all points is at most the FMU's, same H); peer time / FMU time, — when no peer run was "
             "that accurate:", "",
             "| scenario | H | tol | FMU worst point error | " + " | ".join(peers) + " |",
             "| --- | --- | --- | --- |" + " --- |" * len(peers)]
    for e in at_every_point:
        cells = ["—" if e["peers"][p] is None else f"{e['peers'][p]:.2f}" for p in peers]
        lines.append(f"| {e['scenario']} | {e['H']:g} | {e['tol']:.0e} | {e['fmu_point_error']:.1e} | "
                     + " | ".join(cells) + " |")
    return lines


def compiled_target_lines(targets):
    if not targets:
        return []
    lines = ["", "The targets against the compiled peers at tol ≤ 1e-6 (the smallest ratio at equal error at "
             "every point, and at how many tolerances the target is met):", "",
             "| peer | scenario | H | target | smallest ratio | met |", "| --- | --- | --- | --- | --- | --- |"]
    for t in targets:
        lines.append(f"| {t['peer']} | {t['scenario']} | {t['H']:g} | ≥ {t['target']}× | {t['worst']:.2f} | "
                     f"{t['met']} of {t['of']} |")
    return lines


def floor_lines(floor):
    """The distance from the floor, as its range over the tolerances per scenario and H."""
    if not floor:
        return []
    lines = ["", "Distance from the floor: the FMU's time / (its n_rhs × the bare compiled right-hand side, "
             "timed in the same run), over the tolerances run; targets ≤ 1.6 at H = 0.1, ≤ 2 at H = 0.01:", "",
             "| scenario | H | FMU / floor |", "| --- | --- | --- |"]
    for scenario, h in sorted({(f["scenario"], f["H"]) for f in floor}):
        ratios = [f["ratio"] for f in floor if (f["scenario"], f["H"]) == (scenario, h)]
        lines.append(f"| {scenario} | {h:g} s | {min(ratios):.2f}–{max(ratios):.2f} |")
    return lines


def markdown(s):
    lines = [f"Machine: {s['machine']['host']}; {s['machine']['built_from']}; "
             f"one run of `cargo xtask bench`.", "",
             f"Right-hand side with its 2×2 solve: **{s['ns_per_rhs']:.1f} ns per evaluation**"
             + (f" (the bare C right-hand side of the compiled peers: {s['c_ns_per_rhs']:.1f} ns)."
                if s.get("c_ns_per_rhs") else "."), "",
             "FMU through the C ABI against the fastest peer that reaches an equal or smaller final-time error "
             "(scipy: any method; Rust crates: same H). Ratio = peer time / FMU time; — means no peer run was "
             "that accurate.", "",
             "| scenario | H (s) | tol | FMU time (s) | final error | vs scipy | vs Rust crates |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for c in s["comparisons"]:
        lines.append(f"| {c['scenario']} | {c['H']:g} | {c['tol']:.0e} | {c['fmu_seconds']:.2e} | "
                     f"{c['fmu_error']:.1e} | {fmt_ratio(c['scipy_ratio'], c['scipy_method'])} | "
                     f"{fmt_ratio(c['crate_ratio'], c['crate_method'])} |")
    lines += ["", "By communication step (ratios at equal or better error; the targets were ≥ 300× scipy and ≥ 3× "
              "the Rust crates):", "",
              "| H | vs fastest scipy | vs fastest Rust crate | ≥ 300× scipy | ≥ 3× the crates |",
              "| --- | --- | --- | --- | --- |"]
    for row in by_step(s["comparisons"]):
        lines.append("| H = {H:g} s | {scipy} | {crate} | {scipy_met} | {crate_met} |".format(**row))
    if s["promise"]["table"]:
        lines += ["", "The tolerance at every communication point: the FMU's worst error over all points and states, "
                  "in units of tol and of each state's scale max(1, max |y|) (promise: ≤ 10 for tol 1e-3…1e-10; "
                  f"worst in that range {s['promise']['worst']:.2f}):", ""]
        columns = [(sc, h) for sc, hs in s["promise"]["table"].items() for h in hs]
        lines += ["| tol | " + " | ".join(f"{sc} H={float(h):g}" for sc, h in columns) + " |",
                  "| --- |" + " --- |" * len(columns)]
        tols = sorted({t for sc, h in columns for t in s["promise"]["table"][sc][h]}, key=float, reverse=True)
        for t in tols:
            cells = [s["promise"]["table"][sc][h].get(t) for sc, h in columns]
            lines.append(f"| {t} | " + " | ".join("—" if c is None else f"{c:.2f}" for c in cells) + " |")
    lines += at_every_point_lines(s["at_every_point"])
    lines += compiled_target_lines(s.get("compiled_targets"))
    lines += floor_lines(s.get("floor"))
    lines += ["", "Tolerance proportionality (final error in units of the solution's scale, tol 1e-3…1e-10):", "",
              "| run | slope | worst error / tol |", "| --- | --- | --- |"]
    for k, v in s["proportionality"].items():
        lines.append(f"| {k} | {v['slope']:.2f} | {v['worst_error_over_tol']:.1f} |")
    lines += ["", "Run time per right-hand-side evaluation, everything included (median over the tolerances; "
              "the Rust peers and the FMU call the same right-hand side):", "",
              "| method | time per evaluation |", "| --- | --- |"]
    for k, v in s["seconds_per_evaluation"].items():
        lines.append(f"| {k} | {v * 1e9:,.0f} ns |")
    lines += ["", "Case 1 with unchanged inputs: evaluations at H = 1e-3 against H = 0.1 (target ≤ 1.5):",
              "", "| tol | n_rhs at H = 1e-3 | n_rhs at H = 0.1 | ratio |", "| --- | --- | --- | --- |"]
    for w in s["warm_restarts"]:
        lines.append(f"| {w['tol']:.0e} | {w['n_rhs_h_1e_3']} | {w['n_rhs_h_0_1']} | {w['ratio']:.2f} |")
    lines += ["", "FMPy's wall time for the same FMU runs (case 1), and the FMU's share of it:", "",
              "| H (s) | tol | FMPy (s) | FMU share |", "| --- | --- | --- | --- |"]
    for f in s["fmpy"]:
        lines.append(f"| {f['H']:g} | {f['tol']:.0e} | {f['fmpy_seconds']:.3f} | {100 * f['fmu_share']:.1f} % |")
    shares = [100 * f["fmu_share"] for f in s["fmpy"] if f["H"] == 1e-3]
    if shares:
        lines += ["", f"The FMU's share of FMPy's wall time at H = 1 ms: {min(shares):.1f}–{max(shares):.1f} %."]
    if s["stiff"]:
        dop853 = next((r["n_rhs"] for r in s["stiff"] if r["solver"] == "dop853"), None)
        lines += ["", "Stiff couplings (k12 = k34 = 1e7, d12 = d34 = 1e3, paper laws, 1 s, H = 0.01, tol 1e-6), "
                  "through the C ABI; error against the FMU's DOP853 at tol 1e-12:", "",
                  "| solver | n_rhs (Jacobians included) | fewer than dop853 | final error | time (s) |",
                  "| --- | --- | --- | --- | --- |"]
        for r in s["stiff"]:
            fewer = f"{dop853 / r['n_rhs']:.1f}×" if dop853 else "—"
            lines.append(f"| {r['solver']} | {r['n_rhs']} | {fewer} | {r['error']:.1e} | {r['seconds']:.2e} |")
    failed = sorted({(r["method"], r["scenario"]) for r in s["results"] if "failed" in r})
    if failed:
        lines += ["", "Runs that failed: " + ", ".join(f"{m} ({sc})" for m, sc in failed) + "."]
    return "\n".join(lines) + "\n"


def plot(rows, path):
    """Run time against the error at every communication point (what a user plots), for
    the methods the harness runs on the same communication grid; each panel's legend sits
    below it, off the data."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 8.5))
    for ax, name in zip(axes, SCENARIOS):
        methods = sorted({r["method"] for r in rows if r["scenario"] == name and r.get("max_point_error")})
        ax.set_prop_cycle(color=plt.cm.tab20(np.linspace(0, 1, 20)))
        for method in methods:
            for h in sorted({r["H"] for r in rows if r["method"] == method and r.get("max_point_error")}):
                if method != "fmu" and h != 1e-3:
                    continue
                pts = sorted((r["max_point_error"], r["seconds"]) for r in rows if r["method"] == method
                             and r["scenario"] == name and r.get("H") == h and r.get("max_point_error"))
                if pts:
                    style = "-o" if method == "fmu" else ":^"
                    ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, ms=4, label=f"{method} H={h:g}")
        ax.set(xlabel="worst error over every communication point (units of each state's scale)",
               ylabel="run time (s)", title=name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    fig.suptitle("Work-precision: the FMU through its C ABI against the peers, on the same communication grid")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "reference":
        write_references(pathlib.Path(sys.argv[2]), "--quick" in sys.argv)
        sys.exit(0)
    if len(sys.argv) < 4:
        sys.exit("usage: bench.py <harness.json> <CyclicMechanism.fmu> <output directory> [--quick]")
    main(sys.argv[1], pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3]), "--quick" in sys.argv)
