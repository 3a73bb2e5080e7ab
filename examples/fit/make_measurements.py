"""Make the example's "measurements": the FMU itself at chosen parameter values, read
every 20 ms for 5 s, with seeded Gaussian noise added, written to measured.csv.

    python examples/fit/make_measurements.py CyclicMechanism.fmu [OUT.csv] [--seed N]

The fit in fit.toml should then find the chosen values within its intervals. The same FMU
and seed give the same file, bit for bit.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from fmusweep.fmu import Archive, local_runner
from fmusweep.spec import Scenario

HERE = pathlib.Path(__file__).parent
TRUTH = {"k34": 150.0, "d34": 0.8}     # the values the fit should recover
MEASURED = ["omega1", "omega4"]         # two tachometers: the motor and the load
SIGMA = 0.05                            # rad/s, each tachometer's noise
SCENARIO = {"stop": 5.0, "step": 0.01, "tolerance": 1e-8}
EVERY = 2                               # a sample every second communication point


def measurements(fmu: pathlib.Path, seed: int) -> np.ndarray:
    """Rows of time and the measured outputs, noise included."""
    runner = local_runner(Archive.read(fmu))
    scenario = Scenario.of({"scenario": SCENARIO})
    runner.configure(scenario.plan([], {"variables": MEASURED, "every": EVERY}))
    [result] = runner.run(list(TRUTH), [list(TRUTH.values())])
    if result["status"] != "ok":
        raise SystemExit(f"the run at the chosen values failed: {result['message']}")
    rows = np.array(result["series"])
    noise = np.random.default_rng(seed).normal(0.0, SIGMA, size=rows[:, 1:].shape)
    rows[:, 1:] += noise
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("fmu", type=pathlib.Path)
    parser.add_argument("out", type=pathlib.Path, nargs="?", default=HERE / "measured.csv")
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    rows = measurements(args.fmu, args.seed)
    # 17 significant digits: the file holds exactly the numbers made here.
    np.savetxt(args.out, rows, delimiter=",", header=",".join(["time"] + MEASURED),
               comments="", fmt="%.17g")
    print(f"{args.out}: {len(rows)} times of {', '.join(MEASURED)}")


if __name__ == "__main__":
    main()
