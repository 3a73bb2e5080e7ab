"""The sweep benchmark: points per second per worker against a bare C-ABI master loop and
FMPy's simulate_fmu, each kind of FMU the sweep takes (FMI 2.0 and 3.0 Co-Simulation, Model
Exchange integrated by the runner, against FMPy's Model Exchange), Dask's share of the wall time, scaling from 1 to 2 workers, the
per-task cost behind the cluster sizing advice, worker memory over 100 000 points,
every process's memory over a 10⁶-point sweep (10⁴ with --quick), and the client's
high-water mark against the sweep's size (9·10⁴ and 10⁶ points).

    python bench/bench_sweep.py <CyclicMechanism.fmu> <output directory> [--quick]

Writes results.json and results.md. Every ratio comes from runs made side by side in
this one process; absolute times depend on the machine, which the report names.
"""

import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np

from fmusweep import run_sweep
from fmusweep.fmu import Archive, local_runner
from fmusweep.records import new_plan

PAPER_LAWS = {"Mm_a0": 100.0, "Mm_a1": -20.0, "Mm_a2": -1.0, "Mr_b0": 20.0, "Mr_b1": -0.05}
METRICS = {"peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"},
           "omega1_ripple": {"variable": "omega1", "kind": "peak_to_peak", "from": 2.0},
           "n_rhs": {"variable": "n_rhs", "kind": "final"}}


def spec(points: int, stop=10.0, series=False):
    """Paper case 1 (10 s, H = 0.01, tol 1e-8) over k34, `points` values."""
    s = {"scenario": {"stop": stop, "step": 0.01, "tolerance": 1e-8, "parameters": PAPER_LAWS},
         "design": {"kind": "grid", "parameters": {"k34": {"linspace": [90.0, 110.0, points]}}},
         "outputs": {"metrics": METRICS}}
    if series:
        s["outputs"]["series"] = {"variables": ["rod_force", "omega1", "n_rhs"], "interval": 0.01}
    return s


def rows(points):
    return np.linspace(90.0, 110.0, points)[:, None]


def best_of(repeats, f):
    return min(f() for _ in range(repeats))


def per_worker_rates(fmu, n, repeats):
    """Points/s of one worker: the bare loop, the runner through its Python client
    (metrics only, and with every communication point's series), and simulate_fmu."""
    runner = local_runner(Archive.read(fmu))
    plan = {**new_plan(0.0, 10.0, 0.01, tolerance=1e-8), "fixed": PAPER_LAWS,
            "metrics": [{"variable": m["variable"], "kind": m["kind"], "from": m.get("from")}
                        for m in METRICS.values()]}
    runner.configure(plan)
    r = rows(n)

    bare = best_of(repeats, lambda: runner.bare(["k34"], r))
    metrics = best_of(repeats, lambda: timed(lambda: runner.run(["k34"], r)))
    runner.configure(dict(plan, series={"variables": ["rod_force", "omega1", "n_rhs"], "every": 1}))
    series = best_of(repeats, lambda: timed(lambda: runner.run(["k34"], r)))
    import fmpy
    unzipped = fmpy.extract(str(fmu))
    k = max(4, n // 50)

    def simulate():
        for k34 in r[:k, 0]:
            fmpy.simulate_fmu(unzipped, start_values=dict(PAPER_LAWS, k34=k34), stop_time=10.0,
                              output_interval=0.01, relative_tolerance=1e-8,
                              output=["rod_force", "omega1", "n_rhs"])
    simulate_fmu = best_of(repeats, lambda: timed(simulate)) * n / k

    def simulate_all_outputs():
        for k34 in r[:k, 0]:
            fmpy.simulate_fmu(unzipped, start_values=dict(PAPER_LAWS, k34=k34), stop_time=10.0,
                              output_interval=0.01, relative_tolerance=1e-8)
    simulate_fmu_all = best_of(repeats, lambda: timed(simulate_all_outputs)) * n / k
    # The whole sweep in this process (no Dask): spec check, calibration, Parquet parts.
    def whole_sweep(series):
        with tempfile.TemporaryDirectory() as out:
            return run_sweep(spec(n, series=series), fmu=fmu, out=pathlib.Path(out) / "s",
                             serial=True, progress=False, plots=False).summary.dispatch_s
    whole = best_of(repeats, lambda: whole_sweep(False))
    whole_series = best_of(repeats, lambda: whole_sweep(True))
    rate = lambda seconds: n / seconds
    return {
        "points": n,
        "bare_loop": rate(bare),
        "runner_metrics": rate(metrics),
        "runner_series": rate(series),
        "sweep_serial_metrics": rate(whole),
        "sweep_serial_series": rate(whole_series),
        "simulate_fmu": rate(simulate_fmu),
        "simulate_fmu_all_outputs": rate(simulate_fmu_all),
    }


STATES = ["phi1", "omega1", "phi2", "omega2", "phi3", "omega3", "phi4", "omega4"]


def timed(f):
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


def interface_rates(fmu, n, repeats):
    """Points/s of one worker through the runner for each kind of FMU the sweep takes, on
    paper case 1 (10 s, H = 0.01, tol 1e-8, metrics only): the FMU's FMI 2.0 and FMI 3.0
    Co-Simulation archives, its Model Exchange interface integrated by the runner's DOP853,
    and FMPy's simulate_fmu through Model Exchange (CVODE at the same tolerance); and the
    Model Exchange run's worst state error at every communication point against the
    Co-Simulation at tol 1e-12, scaled by 1 + |reference|."""
    fmi3 = fmu.with_name("CyclicMechanism-fmi3.fmu")
    plan = {**new_plan(0.0, 10.0, 0.01, tolerance=1e-8), "fixed": PAPER_LAWS,
            "metrics": [{"variable": m["variable"], "kind": m["kind"], "from": m.get("from")}
                        for m in METRICS.values() if m["variable"] != "n_rhs"]}
    kinds = {"co_simulation_fmi2": (fmu, "co_simulation", None, n),
             "model_exchange_fmi2": (fmu, "model_exchange", None, n),
             "model_exchange_fmi2_radau5": (fmu, "model_exchange", "radau5", max(10, n // 20))}
    if fmi3.exists():
        kinds["co_simulation_fmi3"] = (fmi3, "co_simulation", None, n)
        kinds["model_exchange_fmi3"] = (fmi3, "model_exchange", None, n)
    # Each repeat runs every kind once, one after the other, and each kind keeps its
    # fastest: a busy spell of the machine then slows one repeat of all, not one kind.
    found: dict[str, Any] = {"points": n}
    for _ in range(repeats):
        for key, (archive, interface, integrator, points) in kinds.items():
            runner = local_runner(Archive.read(archive))
            runner.configure(dict(plan, interface=interface, integrator=integrator))
            r = rows(points)
            rate = points / timed(lambda: runner.run(["k34"], r))
            found[key] = max(found.get(key, 0.0), rate)
    r = rows(n)
    import fmpy
    unzipped = fmpy.extract(str(fmu))
    k = max(3, n // 100)

    def simulate():
        for k34 in r[:k, 0]:
            fmpy.simulate_fmu(unzipped, fmi_type="ModelExchange", stop_time=10.0,
                              start_values=dict(PAPER_LAWS, k34=k34), output_interval=0.01,
                              relative_tolerance=1e-8, output=["rod_force", "omega1"])
    found["simulate_fmu_model_exchange"] = k / best_of(repeats, lambda: timed(simulate))
    found["model_exchange_error"] = model_exchange_error(fmu)
    return found


def model_exchange_error(fmu, points=5):
    """The worst scaled state error of the Model Exchange sweep at every communication
    point, against the Co-Simulation sweep at tol 1e-12, for tol 1e-6 and 1e-8 (DOP853)
    and tol 1e-8 (Radau IIA)."""
    def states(tolerance, interface, integrator=None):
        s = spec(points, series=False)
        s["scenario"].update(tolerance=tolerance, interface=interface)
        if integrator:
            s["scenario"]["integrator"] = integrator
        s["outputs"]["series"] = {"variables": STATES}
        with tempfile.TemporaryDirectory() as out:
            series = run_sweep(s, fmu=fmu, out=pathlib.Path(out) / "s", serial=True,
                               progress=False, plots=False).series()
        return series.sort_values(["point", "variable", "time"])["value"].to_numpy()
    reference = states(1e-12, "co_simulation")
    found = {}
    for tolerance, integrator in ((1e-6, None), (1e-8, None), (1e-8, "radau5")):
        mine = states(tolerance, "model_exchange", integrator)
        key = f"{tolerance}" + (f" {integrator}" if integrator else "")
        found[key] = float((abs(mine - reference) / (1 + abs(reference))).max())
    return found


def dask_runs(fmu, n_scaling, n_small, repeats=3):
    """Scaling 1 → 2 workers, Dask's share of the wall time, a small sweep start to end.
    Each cluster size runs `repeats` times, alternating; the fastest run counts (the
    project's timing rule: this machine is shared and noisy)."""
    found = {}
    for _ in range(repeats):
        for workers in (1, 2):
            with tempfile.TemporaryDirectory() as out:
                rep = run_sweep(spec(n_scaling), fmu=fmu, out=pathlib.Path(out) / "s",
                                workers=workers, progress=False, plots=False).summary
            computed = rep.computed - 4  # the calibration points run in the client
            run = {
                "points_per_s": computed / rep.dispatch_s, "dispatch_s": rep.dispatch_s,
                "startup_s": rep.startup_s, "batch_size": rep.batch_size, "batches": rep.batches,
                # Dask's share: the dispatch time the workers did not spend inside points.
                "engine_share": 1 - rep.point_seconds * (computed / rep.computed) / workers / rep.dispatch_s,
            }
            best = found.get(f"workers_{workers}")
            if best is None or run["points_per_s"] > best["points_per_s"]:
                found[f"workers_{workers}"] = run
    found["scaling_1_to_2"] = found["workers_2"]["points_per_s"] / found["workers_1"]["points_per_s"]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        rep = run_sweep(spec(n_small), fmu=fmu, out=pathlib.Path(out) / "s", workers=2,
                        progress=False, plots=False).summary
    found["small_sweep"] = {"points": n_small, "seconds_all_included": time.perf_counter() - t0,
                            "startup_s": rep.startup_s}
    return found


def ssp_rate(fmu, points, stop=1.0):
    """The DC-motor system of examples/dc_motor as an SSP (`stop` s, H = 1 ms; its
    Python-written motor) through FMPy's SSP support, one point after another in this process: points per second of the
    points' own wall times."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "examples/dc_motor"))
    import ssp as example
    with tempfile.TemporaryDirectory() as d:
        system = example.build_ssp(fmu, pathlib.Path(d) / "system")
        spec = {"ssp": str(system), "system": {"engine": "fmpy"},
                "scenario": {"stop": stop, "step": 1e-3},
                "design": {"kind": "grid", "parameters": {"mechanism.Mr_b0": {"linspace": [10.0, 30.0, points]}}},
                "outputs": {"metrics": {"omega1_final": {"variable": "mechanism.omega1", "kind": "final"}}}}
        rep = run_sweep(spec, out=pathlib.Path(d) / "out", serial=True, progress=False, plots=False).summary
    return {"points": points, "points_per_s": rep.computed / rep.point_seconds}


def _noop(x):
    return x


def task_cost(tasks):
    """Dask's cost per task: no-op tasks through a 2-worker LocalCluster."""
    import logging
    from distributed import Client, LocalCluster, wait
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        wait(client.map(_noop, range(50), pure=False))
        t0 = time.perf_counter()
        wait(client.map(_noop, range(tasks), pure=False))
        return (time.perf_counter() - t0) / tasks


def rss_kib(pid):
    for line in pathlib.Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def memory_growth(fmu, total):
    """The runner's and the worker's resident memory after 10 % and after all of `total`
    one-second points, in batches of 1000 as a worker would run them."""
    runner = local_runner(Archive.read(fmu))
    runner.configure({**new_plan(0.0, 1.0, 0.01, tolerance=1e-8), "fixed": PAPER_LAWS,
                      "metrics": [{"variable": "rod_force", "kind": "peak_abs"}]})
    r = rows(1000)
    marks = {}
    for b in range(total // 1000):
        runner.run(["k34"], r)
        if b + 1 in (total // 10000, total // 1000):
            marks[b + 1] = (rss_kib(runner.process.pid), rss_kib(os.getpid()))
    (r1, p1), (r2, p2) = marks[total // 10000], marks[total // 1000]
    return {"points": total, "runner_rss_kib": [r1, r2], "python_rss_kib": [p1, p2],
            "runner_growth": (r2 - r1) / r1, "python_growth": (p2 - p1) / p1}


def parents():
    """Each process's parent, from /proc."""
    found = {}
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            found[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
    return found


def process_kind(pid):
    try:
        command = pathlib.Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
    except OSError:
        return None
    if b"fmu-runner" in command:
        return "runner"
    if b"spawn_main" in command:
        return "worker"
    return None


def sweep_memory(fmu, per_axis, series):
    """Resident memory of the client (with its own runner), of each Dask worker and of each
    worker's runner at 10 %, 50 % and 100 % of a per_axis² sweep of 1 s runs on a
    LocalCluster of 2 workers (metrics only, or with series decimated to 0.1 s)."""
    marks, taken = (0.1, 0.5, 1.0), {}

    def sample(done, total):
        for mark in marks:
            if mark not in taken and done >= mark * total:
                parent = parents()

                def below(pid, kind):
                    return sorted(p for p, q in parent.items() if q == pid and process_kind(p) == kind)

                me = os.getpid()
                # The client's own runner (the calibration batch) is its child.
                rss = {"client (with its runner)":
                       rss_kib(me) + sum(rss_kib(p) for p in below(me, "runner"))}
                for i, worker in enumerate(below(me, "worker")):
                    rss[f"worker {i + 1}"] = rss_kib(worker)
                    rss[f"runner of worker {i + 1}"] = sum(rss_kib(p) for p in below(worker, "runner"))
                taken[mark] = rss

    s = {"scenario": {"stop": 1.0, "step": 0.01, "tolerance": 1e-8, "parameters": PAPER_LAWS},
         "design": {"kind": "grid", "parameters": {
             "k34": {"linspace": [50.0, 400.0, per_axis]}, "L": {"linspace": [0.6, 0.7, per_axis]}}},
         "outputs": {"metrics": {"peak_rod_force": {"variable": "rod_force", "kind": "peak_abs"}}}}
    if series:
        s["outputs"]["series"] = {"variables": ["rod_force"], "interval": 0.1}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        results = run_sweep(s, fmu=fmu, out=pathlib.Path(tmp) / "out", workers=2,
                            progress=False, plots=False, on_batch=sample)
        wall = time.perf_counter() - t0
    return {"points": per_axis ** 2, "series": series, "wall_s": wall,
            "batch_size": results.summary.batch_size, "batches": results.summary.batches,
            "held_results": results.summary.held_results,
            "rss_kib": {str(m): taken[m] for m in marks},
            "growth": {name: (taken[1.0][name] - kib) / kib for name, kib in taken[0.1].items()}}


def client_memory(fmu, per_axis):
    """The client's memory over a per_axis² sweep, in a process of its own
    (client_memory.py): its resident memory before, its high-water mark, and per point."""
    script = pathlib.Path(__file__).with_name("client_memory.py")
    done = subprocess.run([sys.executable, str(script), str(fmu), str(per_axis)], check=True,
                          capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def built_from():
    """The commit the measured build comes from, marked when the working tree's sources
    differ from it, so that a report says which code it measured."""
    root = pathlib.Path(__file__).resolve().parent.parent
    def git(*args):
        done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True)
        return done.stdout.strip() if done.returncode == 0 else ""
    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    changed = git("status", "--porcelain", "--", "src", "integrators", "runner", "python",
                  "bench", "examples", "Cargo.lock")
    return f"commit {commit}" + (" with uncommitted changes" if changed else "")


def machine():
    """The machine and the build a report measured."""
    return f"{host()}; {built_from()}"


def host():
    cpu = "unknown"
    for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            cpu = line.split(":", 1)[1].strip()
            break
    return f"{platform.machine()}, {os.cpu_count()} cores ({cpu}), Linux {platform.release()}"


def arguments():
    """A benchmark's command line, FMU OUT [--quick]: the FMU, the output directory
    (made), whether quick, and the results begun with the machine."""
    fmu, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    quick = "--quick" in sys.argv
    out.mkdir(parents=True, exist_ok=True)
    return fmu, out, quick, {"machine": machine(), "quick": quick}


def write_results(out: pathlib.Path, r: dict, text: str):
    """results.json (every figure) and results.md (the report), and the report shown."""
    (out / "results.json").write_text(json.dumps(r, indent=2))
    (out / "results.md").write_text(text)
    print(text)


def report(r) -> str:
    w = r["per_worker"]
    bare = w["bare_loop"]
    d = r["dask"]
    lines = [
        "# Sweep benchmark", "",
        f"Machine: {r['machine']}. Paper case 1 (10 s, H = 0.01, tol 1e-8), metrics "
        "peak |rod_force|, peak-to-peak omega1 after 2 s, n_rhs. Ratios from one run; each "
        "figure the fastest of several runs.", "",
        "| path (one worker) | points/s | of the bare loop |", "| --- | --- | --- |",
    ]
    for key, label in (("bare_loop", "bare C-ABI master loop (in the runner)"),
                       ("runner_metrics", "runner through its Python client, metrics"),
                       ("sweep_serial_metrics", "whole sweep, serial, metrics + Parquet"),
                       ("runner_series", "runner, series at every communication point"),
                       ("sweep_serial_series", "whole sweep, serial, series + Parquet"),
                       ("simulate_fmu", "FMPy simulate_fmu per point, the same 3 outputs"),
                       ("simulate_fmu_all_outputs", "FMPy simulate_fmu per point, its default outputs")):
        if w.get(key):
            lines.append(f"| {label} | {w[key]:,.0f} | {w[key] / bare:.1%} |")
    lines += ["", f"Sweep (metrics) against simulate_fmu per worker: "
              f"{w['sweep_serial_metrics'] / w['simulate_fmu']:.0f}× (the same 3 outputs), "
              f"{w['sweep_serial_metrics'] / w['simulate_fmu_all_outputs']:.0f}× (its default outputs).", "",
              ] + interface_report(r["interfaces"]) + [
              "| LocalCluster (fastest of 3) | points/s | batch | batches | Dask's share of the dispatch time | start-up s |",
              "| --- | --- | --- | --- | --- | --- |"]
    for n in (1, 2):
        x = d[f"workers_{n}"]
        lines.append(f"| {n} worker{'s' if n > 1 else ''} | {x['points_per_s']:,.0f} | {x['batch_size']} | "
                     f"{x['batches']} | {x['engine_share']:.1%} | {x['startup_s']:.2f} |")
    s = d["small_sweep"]
    lines += ["", f"Scaling 1 → 2 workers: {d['scaling_1_to_2']:.2f}×. A {s['points']}-point sweep on "
              f"2 workers, cluster start-up included: {s['seconds_all_included']:.2f} s.", "",
              f"Dask's cost per task (no-op tasks, 2 workers): {r['task_cost_s'] * 1e3:.2f} ms. "
              f"{r['cluster_advice']}", ""]
    lines += [f"A coupled SSP system (examples/dc_motor: the mechanism and a pythonfmu DC motor, "
              f"1 s at H = 1 ms) through FMPy's simulate_ssp: {r['ssp']['points_per_s']:.1f} points/s "
              "per worker.", ""]
    if "memory" in r:
        m = r["memory"]
        lines.append(f"Memory over {m['points']:,} one-second points: runner RSS "
                     f"{m['runner_rss_kib'][0]} → {m['runner_rss_kib'][1]} KiB "
                     f"({m['runner_growth']:+.1%}), worker RSS {m['python_rss_kib'][0]} → "
                     f"{m['python_rss_kib'][1]} KiB ({m['python_growth']:+.1%}).")
    for m in r.get("sweep_memory", []):
        kind = "series every 0.1 s" if m["series"] else "metrics only"
        lines += ["", f"A {m['points']:,}-point sweep ({kind}; 1 s runs, 2 workers, batches of "
                  f"{m['batch_size']:,}, {m['wall_s']:.0f} s; {m['held_results']} results held at "
                  "the end), resident memory in MiB at 10 % / 50 % / 100 %:", "",
                  "| process | 10 % | 50 % | 100 % | growth 10 → 100 % |", "| --- | --- | --- | --- | --- |"]
        at = m["rss_kib"]
        for name, growth in m["growth"].items():
            a, b, c = (at[k][name] / 1024 for k in ("0.1", "0.5", "1.0"))
            what = "series" if m["series"] else "metrics"
            lines.append(f"| {name}, {what} | {a:.0f} | {b:.0f} | {c:.0f} | {growth:+.1%} |")
    if r.get("client_memory"):
        lines += ["", "The client's memory against the sweep's size (metrics only; 1 s runs, 2 "
                  "workers; a process of its own; the LocalCluster's scheduler runs in it, its "
                  "runner does not), in MiB:", "",
                  "| points | before the sweep | high-water mark | above before, per point |",
                  "| --- | --- | --- | --- |"]
        for m in r["client_memory"]:
            lines.append(f"| {m['points']:,} | {m['before_kib'] / 1024:.0f} | "
                         f"{m['peak_kib'] / 1024:.0f} | {m['bytes_per_point']:.0f} B |")
        small, large = r["client_memory"][0], r["client_memory"][-1]
        slope = ((large["peak_kib"] - small["peak_kib"]) * 1024
                 / (large["points"] - small["points"]))
        lines += ["", f"Growth of the high-water mark from {small['points']:,} to "
                  f"{large['points']:,} points: {slope:.0f} bytes per point."]
    return "\n".join(lines) + "\n"


def interface_report(k) -> list[str]:
    cs = k["co_simulation_fmi2"]
    lines = ["Each kind of FMU the sweep takes, one worker, the runner through its Python client "
             f"(paper case 1, metrics only, {k['points']} points; FMPy per point):", "",
             "| kind | points/s | of FMI 2.0 Co-Simulation |", "| --- | --- | --- |"]
    for key, label in (("co_simulation_fmi2", "FMI 2.0 Co-Simulation (the FMU's own integrator)"),
                       ("co_simulation_fmi3", "FMI 3.0 Co-Simulation, event mode"),
                       ("model_exchange_fmi2", "FMI 2.0 Model Exchange, the runner's DOP853"),
                       ("model_exchange_fmi3", "FMI 3.0 Model Exchange, the runner's DOP853"),
                       ("model_exchange_fmi2_radau5", "FMI 2.0 Model Exchange, the runner's Radau IIA"),
                       ("simulate_fmu_model_exchange", "FMPy simulate_fmu, Model Exchange (CVODE)")):
        if k.get(key):
            lines.append(f"| {label} | {k[key]:,.1f} | {k[key] / cs:.1%} |")
    e = k["model_exchange_error"]
    lines += ["", f"Model Exchange through the runner against FMPy's: "
              f"{k['model_exchange_fmi2'] / k['simulate_fmu_model_exchange']:.0f}×. Its worst "
              f"state error at every communication point, against the Co-Simulation at tol "
              f"1e-12 (scaled by 1 + |reference|): {e['1e-06']:.2e} at tol 1e-6, "
              f"{e['1e-08']:.2e} at tol 1e-8 (DOP853); {e['1e-08 radau5']:.2e} at tol 1e-8 "
              "(Radau IIA).", ""]
    return lines


def main():
    fmu, out, quick, r = arguments()
    print("bench-sweep: per-worker rates", flush=True)
    r["per_worker"] = per_worker_rates(fmu, 200 if quick else 2000, 2 if quick else 5)
    print("bench-sweep: each kind of FMU", flush=True)
    r["interfaces"] = interface_rates(fmu, 100 if quick else 1000, 2 if quick else 5)
    print("bench-sweep: Dask runs", flush=True)
    r["dask"] = dask_runs(fmu, 1000 if quick else 8000, 1000)
    print("bench-sweep: an SSP system through FMPy", flush=True)
    r["ssp"] = ssp_rate(fmu, 4 if quick else 12)
    print("bench-sweep: Dask's cost per task", flush=True)
    r["task_cost_s"] = task_cost(300 if quick else 2000)
    # A worker is kept busy when its batch lasts longer than the scheduler needs to serve
    # every other worker once: batch seconds ≥ workers × cost per task.
    busy = 64 * r["task_cost_s"]
    per_point = 1 / r["per_worker"]["runner_metrics"]
    r["cluster_advice"] = (
        f"On 64 cores, batches of ≥ {busy:.2f} s keep the scheduler below one task per "
        f"worker at a time; the default 0.5 s batches ({0.5 / per_point:,.0f} points of this case) "
        f"leave it {busy / 0.5:.0%} busy, and 4 batches per worker need ≥ {4 * 64 * 0.5 / per_point:,.0f} points.")
    if not quick:
        print("bench-sweep: memory over 100 000 points", flush=True)
        r["memory"] = memory_growth(fmu, 100_000)
    per_axis = 100 if quick else 1000
    print(f"bench-sweep: memory of a {per_axis ** 2:,}-point sweep on 2 workers", flush=True)
    r["sweep_memory"] = [sweep_memory(fmu, per_axis, series) for series in (False, True)]
    print("bench-sweep: the client's memory against the number of points", flush=True)
    r["client_memory"] = [client_memory(fmu, n) for n in ((30, 100) if quick else (300, 1000))]
    write_results(out, r, report(r))


if __name__ == "__main__":
    main()
