"""The fmusweep package as a user meets it: `pip install ./python` in a fresh environment,
its version, a --help whose example runs, a typed package (py.typed), and no import cycle
among its modules."""

import ast
import os
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


def _module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts) or "__init__"


def _relative_imports(path: pathlib.Path, name: str) -> set[str]:
    """The package's modules that `path` imports at module level, by dotted name."""
    package = name.split(".")[:-1] if path.name != "__init__.py" else name.split(".")
    if name == "__init__":
        package = []
    found = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.ImportFrom) and node.level >= 1:
            base = package[:len(package) - (node.level - 1)]
            if node.module:
                found.add(".".join(base + node.module.split(".")))
            else:
                found.update(".".join(base + [alias.name]) for alias in node.names)
    return found


def test_no_import_cycle_among_the_modules():
    """Module-level relative imports, subpackages included, form no cycle (imports inside
    functions are left out: they run later). A package's import of its own __init__ from a
    submodule would be one, and is found like any other."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        targets = set()
        for target in _relative_imports(path, name):
            # `from .fitting import fit`: the package fitting (its __init__), or a module.
            targets.add(target if target in modules else target.rsplit(".", 1)[0])
        graph[name] = {t for t in targets if t in modules and t != name}
    visiting, done = set(), set()

    def visit(module, trail):
        if module in done:
            return
        assert module not in visiting, "import cycle: " + " -> ".join(trail + [module])
        visiting.add(module)
        for other in graph[module]:
            visit(other, trail + [module])
        visiting.discard(module)
        done.add(module)

    for module in graph:
        visit(module, [])
    assert "fitting.run" in graph["fitting"] and "fitting.method" in graph["fitting.run"]
    assert "designs" not in graph["errors"] and "spec" not in graph["designs"]


def test_pip_installs_the_package_in_a_fresh_environment(fmu_path, tmp_path):
    """`pip install ./python` as a user runs it: maturin builds the runner from source, pip
    pulls the dependencies, and the installed package finds its runner and sweeps."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    python = venv / "bin/python"
    env = {k: v for k, v in os.environ.items() if k not in ("FMUSWEEP_RUNNER", "PYTHONPATH")}
    # The runner built without link-time optimisation, in parallel: what is tested here is
    # that the package builds, installs and runs, not its speed; the whole-program LTO of a
    # cold build would take minutes of the suite.
    build = dict(env, CARGO_PROFILE_RELEASE_LTO="off", CARGO_PROFILE_RELEASE_CODEGEN_UNITS="16")
    done = subprocess.run([str(python), "-m", "pip", "install", "--quiet", str(ROOT / "python")],
                          capture_output=True, text=True, env=build)
    assert done.returncode == 0, done.stderr[-3000:]
    version = subprocess.run([str(python), "-m", "fmusweep", "--version"], capture_output=True,
                             text=True, env=env, cwd=tmp_path)
    assert version.returncode == 0 and version.stdout.startswith("fmusweep 0."), version.stderr
    (tmp_path / "sweep.toml").write_text(
        f'fmu = "{fmu_path.resolve()}"\n[scenario]\nstop = 1.0\nstep = 0.01\n'
        '[design]\nparameters = { k34 = { values = [50.0, 100.0] } }\n'
        '[outputs.metrics]\nfinal = { variable = "omega1", kind = "final" }\n')
    sweep = subprocess.run([str(python), "-m", "fmusweep", "sweep.toml", "--serial", "--no-progress",
                            "--no-plots", "--out", "out"], capture_output=True, text=True,
                           env=env, cwd=tmp_path)
    assert sweep.returncode == 0, sweep.stderr
    assert "2 points" in sweep.stdout
