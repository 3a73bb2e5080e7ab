"""The accuracy report: the figures the tests measured (the `report` fixture's
measurements.json), one row each, with the commit and machine, as docs/bench/accuracy.md.
A figure's row is its name; a list's values share its row; a table of figures gives a row
per entry (name.entry).

    python bench/accuracy_report.py MEASUREMENTS.json OUT.md TEST_FILE ...
"""

import json
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_sweep import machine  # noqa: E402


def shown(value):
    """A figure as printed: three significant digits, integers whole."""
    if isinstance(value, (bool, int)):
        return str(value)
    if isinstance(value, float):
        return f"{value:#.3g}"
    if isinstance(value, list):
        return " / ".join(shown(v) for v in value)
    return str(value)


def rows(figures):
    for name, value in sorted(figures.items()):
        if isinstance(value, dict):
            for entry, inner in sorted(value.items()):
                yield f"{name}.{entry}", shown(inner)
        else:
            yield name, shown(value)


def main(measurements, out, files):
    figures = json.loads(pathlib.Path(measurements).read_text())
    lines = ["# Accuracy, as the tests measure it", "",
             f"Machine: {machine()}. Written by `cargo xtask accuracy`, which runs the tests that "
             f"measure these figures ({', '.join(files)}) on the linux64 FMU and tables what they "
             "measured; each test holds its figure by a bound of its own. Errors against the "
             "independent reference (tests/python/reference.py) are in units of each state's "
             "scale max(1, max |y|) unless the name says otherwise.", "",
             "| figure | measured |", "| --- | --- |"]
    lines += [f"| {name} | {value} |" for name, value in rows(figures)]
    pathlib.Path(out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3:])
