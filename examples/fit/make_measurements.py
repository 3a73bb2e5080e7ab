"""Make the examples' "measurements": the FMU itself at chosen parameter values, read
every 20 ms, with seeded Gaussian noise added:

- measured.csv for fit.toml: 5 s of the paper's case at the chosen k34 and d34;
- braked.csv and boosted.csv for two_experiments.toml: 4 s with a brake torque and with
  a boost torque on the motor (the input M_m), each from its own starting speed.

    python examples/fit/make_measurements.py CyclicMechanism.fmu [OUT_DIR] [--seed N]

The fits should then find the chosen values within their intervals. The same FMU and
seed give the same files, bit for bit.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from fmusweep.fmu import Archive, local_runner
from fmusweep.spec import Scenario

HERE = pathlib.Path(__file__).parent
MEASURED = ["omega1", "omega4"]         # two tachometers: the motor and the load
SIGMA = 0.05                            # rad/s, each tachometer's noise
EVERY = 2                               # a sample every second communication point
STEP = 0.01
# Each file: its run's stop time, its inputs, and the values the fit should recover.
RUNS = {
    "measured": (5.0, {}, {"k34": 150.0, "d34": 0.8}),
    "braked": (4.0, {"M_m": -85.0}, {"Mm_a0": 100.0, "Mm_a1": -20.0, "omega1_0": 0.5}),
    "boosted": (4.0, {"M_m": 40.0}, {"Mm_a0": 100.0, "Mm_a1": -20.0, "omega1_0": 5.0}),
}


def measurements(fmu: pathlib.Path, run: str, seed: int) -> np.ndarray:
    """Rows of time and the measured outputs, noise included."""
    stop, inputs, truth = RUNS[run]
    runner = local_runner(Archive.read(fmu))
    scenario = Scenario.of({"scenario": {"stop": stop, "step": STEP, "tolerance": 1e-8,
                                         "inputs": inputs}})
    runner.configure(scenario.plan([], {"variables": MEASURED, "every": EVERY}))
    [result] = runner.run(list(truth), [list(truth.values())])
    if result["status"] != "ok":
        raise SystemExit(f"the run {run} at the chosen values failed: {result['message']}")
    rows = np.array(result["series"])
    noise = np.random.default_rng(seed).normal(0.0, SIGMA, size=rows[:, 1:].shape)
    rows[:, 1:] += noise
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("fmu", type=pathlib.Path)
    parser.add_argument("out", type=pathlib.Path, nargs="?", default=HERE)
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    for k, run in enumerate(RUNS):
        rows = measurements(args.fmu, run, args.seed + k)
        path = args.out / f"{run}.csv"
        # 17 significant digits: the file holds exactly the numbers made here.
        np.savetxt(path, rows, delimiter=",", header=",".join(["time"] + MEASURED),
                   comments="", fmt="%.17g")
        print(f"{path}: {len(rows)} times of {', '.join(MEASURED)}")


if __name__ == "__main__":
    main()
