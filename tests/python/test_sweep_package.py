"""The fmusweep package as a user meets it: its version, a --help whose example runs, a
typed package (py.typed), and no import cycle among its modules."""

import ast
import pathlib
import subprocess
import sys

import fmusweep
from fmusweep.cli import EXAMPLE

from conftest import ROOT

PACKAGE = ROOT / "python/fmusweep"


def fmusweep_command(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "fmusweep", *args], capture_output=True,
                          text=True, **kwargs)


def test_version_and_help():
    version = fmusweep_command("--version")
    assert version.returncode == 0 and version.stdout.strip() == f"fmusweep {fmusweep.__version__}"
    help_text = fmusweep_command("--help").stdout
    assert "example:" in help_text and "python -m fmusweep sweep.toml" in help_text


def test_the_help_example_runs(fmu_path, tmp_path):
    toml = EXAMPLE.split("with sweep.toml:\n", 1)[1]
    toml = "\n".join(line[2:] for line in toml.splitlines())
    spec = tmp_path / "sweep.toml"
    spec.write_text(toml.replace('"CyclicMechanism.fmu"', repr(str(fmu_path.resolve())).replace("'", '"')))
    done = fmusweep_command(str(spec), "--serial", "--no-progress", "--no-plots",
                            "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    results = fmusweep.load_results(tmp_path / "out")
    assert len(results.points) == 10 and (results.points["status"] == "ok").all()


def test_the_installed_package_is_typed():
    assert (pathlib.Path(fmusweep.__file__).parent / "py.typed").exists()


def test_no_import_cycle_among_the_modules():
    """Module-level relative imports form no cycle (imports inside functions are left
    out: they run later)."""
    graph = {}
    for path in PACKAGE.glob("*.py"):
        tree = ast.parse(path.read_text())
        imported = set()
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                if node.module:
                    imported.add(node.module.split(".")[0])
                else:
                    imported.update(alias.name for alias in node.names)
        graph[path.stem] = imported - {path.stem}
    visiting, done = set(), set()

    def visit(module, trail):
        if module in done or module not in graph:
            return
        assert module not in visiting, "import cycle: " + " -> ".join(trail + [module])
        visiting.add(module)
        for other in graph[module]:
            visit(other, trail + [module])
        visiting.discard(module)
        done.add(module)

    for module in graph:
        visit(module, [])
    assert "design" not in graph["errors"] and "spec" not in graph["design"]
