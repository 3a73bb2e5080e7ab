"""The tables of a focused harness run (`bench … --steps 0.01,0.1 --only fmu,hairer_dop853,…`,
no scipy or FMPy): peer time / FMU time at equal error at every communication point, the
targets against Hairer's DOP853 and LSODA, the FMU's distance from the floor, and its worst
point error / tol. The tables are bench.py's own, as in a full run's results.md.

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
    lines = [f"Right-hand side: the model's {harness['ns_per_rhs']:.1f} ns, "
             f"the bare C one {harness['c_ns_per_rhs']:.1f} ns per evaluation."]
    lines += bench.at_every_point_lines(at_points)
    lines += bench.compiled_target_lines(bench.compiled_targets(at_points))
    lines += bench.floor_lines(bench.distance_from_floor(fmu_rows, harness["c_ns_per_rhs"]))
    lines += ["", "The FMU's worst point error / tol, tol 1e-3…1e-10: "
              f"{bench.tolerance_promise(fmu_rows)['worst']:.2f}"]
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1])
