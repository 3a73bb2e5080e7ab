"""The tables of a focused harness run (`bench … --steps 0.01,0.1 --only fmu,hairer_dop853,…`,
no scipy or FMPy): peer time / FMU time at equal error at every communication point, the
targets against Hairer's DOP853 and LSODA, the FMU's distance from the floor, and its worst
point error / tol. It uses bench.py's own functions, so the tables match a full run's
results.md.

    python bench/focused.py target/bench/focused.json
"""

import json
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench  # noqa: E402


def main(path):
    harness = json.loads(pathlib.Path(path).read_text())
    rows = [{k: v for k, v in r.items() if k != "states"} for r in harness["results"]]
    fmu_rows = [r for r in rows if r["method"] == "fmu"]
    at_points = bench.point_comparisons(rows, fmu_rows)
    print(f"Right-hand side: the model's {harness['ns_per_rhs']:.1f} ns, "
          f"the bare C one {harness['c_ns_per_rhs']:.1f} ns per evaluation.\n")
    peers = sorted({p for e in at_points for p in e["peers"]})
    print("| scenario | H | tol | FMU worst point error | " + " | ".join(peers) + " |")
    print("| --- | --- | --- | --- |" + " --- |" * len(peers))
    for e in at_points:
        cells = ["—" if e["peers"][p] is None else f"{e['peers'][p]:.2f}" for p in peers]
        print(f"| {e['scenario']} | {e['H']:g} | {e['tol']:.0e} | {e['fmu_point_error']:.1e} | "
              + " | ".join(cells) + " |")
    print("\n| peer | scenario | H | target | smallest ratio at tol ≤ 1e-6 | met |")
    print("| --- | --- | --- | --- | --- | --- |")
    for t in bench.compiled_targets(at_points):
        print(f"| {t['peer']} | {t['scenario']} | {t['H']:g} | ≥ {t['target']}× | {t['worst']:.2f} | "
              f"{t['met']} of {t['of']} |")
    floor = bench.distance_from_floor(fmu_rows, harness["c_ns_per_rhs"])
    print("\n| scenario | H | FMU / floor over tol 1e-3…1e-12 |\n| --- | --- | --- |")
    for key in sorted({(f["scenario"], f["H"]) for f in floor}):
        ratios = [f["ratio"] for f in floor if (f["scenario"], f["H"]) == key]
        print(f"| {key[0]} | {key[1]:g} | {min(ratios):.2f}–{max(ratios):.2f} |")
    print(f"\nThe FMU's worst point error / tol, tol 1e-3…1e-10: "
          f"{bench.tolerance_promise(fmu_rows)['worst']:.2f}")


if __name__ == "__main__":
    main(sys.argv[1])
