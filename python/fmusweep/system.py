"""Coupled systems named in a spec's ``[system]`` table: components (FMI 2.0 or 3.0
co-simulation FMUs) and connections from an output of one to an input of another::

    [system]
    components = { motor = "DcMotor.fmu", mechanism = "CyclicMechanism.fmu" }
    connections = [["motor.torque", "mechanism.M_m"], ["mechanism.omega1", "motor.omega"]]

    engine = "native"          # default; or "container"
    input_derivatives = 2      # native only: 0 holds inputs over a step
    coupling_tolerance = 1e-4  # native only: the system chooses its communication steps

The system runs in the native runner, with no Python per communication step, by one of
two engines:

- ``native`` (the default): the runner loads every component and steps them together.
  At each communication step it passes each connection's output to its input, then steps
  every component over the step (Jacobi). Where the source gives output derivatives and
  the target interpolates inputs, it also passes the derivatives up to order
  ``input_derivatives``: the target then moves its input along the source's Taylor
  polynomial over the step instead of holding it, and the coupling error falls as H^(k+1)
  instead of H.
  With ``coupling_tolerance`` the native engine chooses each communication step itself,
  inside each step of the scenario's grid, from an estimate of the coupling error (how
  far each source's output drifted from what its target was given over the step, in
  units of max(1, its largest |value|)); a step whose estimate exceeds the tolerance is
  taken again, shorter, from every component's saved FMU state, so every component must
  be able to save and restore it (``canGetAndSetFMUstate``). Each point then reports its
  largest estimate and its accepted and rejected steps.
- ``container``: a container FMU (fmu-manipulation-toolbox's, whose compiled master holds
  each input over the step) built once per sweep and run as one FMU.

Every parameter of a component is ``component.parameter``, every output
``component.output``, every input left unconnected ``component.input``; the sweep's
designs, metrics and series address them so (the native engine also shows the
components' other variables). Everything is checked before anything runs: names, files,
each connection's ends and types, inputs fed twice, algebraic loops.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import io
import json
import logging
import os
import pathlib
import re
import shutil
import tempfile
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from .errors import Collector, SpecError, refuse
from .fields import finite
from .fmu import Archive, local_runner, open_for_checks
from .native import NativeRunner, RunnerError, describe_unpacked
from .records import new_plan
from .ssd import SspContents

__all__ = ["System", "load_system"]

NAME = re.compile(r"[a-z][a-z0-9_]*\Z")


@dataclass(frozen=True)
class Connection:
    source: str   # component
    output: str
    target: str   # component
    input: str

    def __str__(self) -> str:
        return f"{self.source}.{self.output} → {self.target}.{self.input}"


ENGINES = ("native", "container")
# What a [system] table sets besides its components and connections (all a [system] beside
# an SSP file may set).
OPTIONS = ("engine", "input_derivatives", "coupling_tolerance")


@dataclass
class System:
    components: dict[str, pathlib.Path]
    connections: list[Connection]
    engine: str = "native"
    input_derivatives: int = 2
    coupling_tolerance: float | None = None
    # Where the components and connections were given, for the fields that name a mistake:
    # the spec's [system] table, or an SSP file.
    origin: str = "system"

    # --- the spec's fields ---------------------------------------------------------------
    @staticmethod
    def of(table: object, base_dir: pathlib.Path) -> System:
        if not isinstance(table, dict):
            raise SpecError("system", "must be a table with components and connections")
        fields = {"components", "connections", *OPTIONS}
        errors = Collector()
        unknown = sorted(set(table) - fields)
        for key in unknown:
            errors.run(lambda: refuse(f"system.{key}", "unknown field; expected "
                                      + ", ".join(sorted(fields))))
        options = errors.run(lambda: _options(table, ENGINES))
        components = table.get("components")
        if not isinstance(components, dict) or not components:
            errors.run(lambda: refuse("system.components", "must name at least one component: "
                                                           "name = \"file.fmu\""))
            components = {}
        paths = {}
        for name, path in components.items():
            errors.run(lambda: _component(name, path))
            paths[name] = base_dir / path if isinstance(path, str) else base_dir
        connections = table.get("connections", [])
        if not isinstance(connections, list):
            errors.run(lambda: refuse("system.connections", "must be a list of "
                                      "[\"component.output\", \"component.input\"] pairs"))
            connections = []
        parsed = [errors.run(lambda: _connection(i, c, paths)) for i, c in enumerate(connections)]
        parsed_connections = [c for c in parsed if c is not None]
        if errors.errors and len(parsed_connections) == len(connections) and paths:
            # The options' mistakes and the connections' own, in the same run.
            errors.run(lambda: System(paths, parsed_connections).check())
        errors.raise_any()
        assert options is not None
        engine, derivatives, tolerance = options
        return System(paths, parsed_connections, engine, derivatives, tolerance)

    @staticmethod
    def from_ssp(path: pathlib.Path, contents: SspContents, table: object) -> System:
        """The system an SSP file describes (`contents`, read from `path`), its components
        unpacked into this process's folder for them; `table` is the spec's [system]
        beside it, which may only choose how it runs."""
        options = {} if table is None else table
        if not isinstance(options, dict):
            raise SpecError("system", "must be a table")
        unknown = sorted(set(options) - set(OPTIONS))
        if unknown:
            raise SpecError(f"system.{unknown[0]}", "the SSP file gives the components and "
                            "connections; beside ssp, [system] takes " + ", ".join(OPTIONS))
        # "fmpy" is handled before a system is made (it runs no system of the runner's).
        engine, derivatives, tolerance = _options(options, (*ENGINES, "fmpy"))
        directory = _unpacked_components(path, contents)
        connections = [Connection(c.source, c.output, c.target, c.input)
                       for c in contents.connections]
        for i, c in enumerate(connections):
            for component in (c.source, c.target):
                if component not in contents.components:
                    raise SpecError("ssp", f"{path.name}: connection {i} ({c}) names no component "
                                           f"of the system ({', '.join(contents.components)})")
        return System({name: directory / f"{name}.fmu" for name in contents.components},
                      connections, engine, derivatives, tolerance, origin="ssp")

    # --- checks against the components -------------------------------------------------
    def check(self) -> dict[str, Any]:
        """Each component's model description; each connection checked against them."""
        descriptions = {name: _description(f"{self.origin}.components.{name}", path)
                        for name, path in self.components.items()}
        if self.engine == "native":
            for name, description in descriptions.items():
                _refuse_python_written(f"{self.origin}.components.{name}", description)
        if self.coupling_tolerance is not None:
            for name, description in descriptions.items():
                if not description["can_get_and_set_state"]:
                    raise SpecError(f"{self.origin}.components.{name}",
                                    "system.coupling_tolerance takes a step again from every "
                                    "component's saved state, and this FMU cannot save its "
                                    "state (canGetAndSetFMUstate is false)")
        fed: dict[tuple[str, str], int] = {}
        errors = Collector()
        for i, c in enumerate(self.connections):
            errors.run(lambda: self._check_connection(i, c, descriptions, fed))
        errors.raise_any()
        loop = _algebraic_loop(self.connections, descriptions)
        if loop:
            raise SpecError(f"{self.origin}.connections", "an algebraic loop (each output depends "
                            "directly on the input before it): " + " → ".join(loop))
        return descriptions

    def _check_connection(self, i: int, c: Connection, descriptions: dict[str, Any],
                          fed: dict[tuple[str, str], int]) -> None:
        where = f"{self.origin}.connections[{i}]"
        errors = Collector()
        source = errors.run(lambda: _variable(descriptions[c.source], c.source, c.output, where))
        target = errors.run(lambda: _variable(descriptions[c.target], c.target, c.input, where))
        errors.raise_any()
        assert source is not None and target is not None
        if source["causality"] != "output":
            raise SpecError(where, f"{c.source}.{c.output} has causality {source['causality']}; "
                                   "a connection starts at an output")
        if target["causality"] != "input":
            raise SpecError(where, f"{c.target}.{c.input} has causality {target['causality']}; "
                                   "a connection ends at an input")
        if source["type"] != target["type"]:
            raise SpecError(where, f"{c}: a {source['fmi_type']} output cannot feed a "
                                   f"{target['fmi_type']} input")
        if (c.target, c.input) in fed:
            raise SpecError(where, f"{c.target}.{c.input} is fed twice (also by connection "
                                   f"{fed[(c.target, c.input)]})")
        fed[(c.target, c.input)] = i

    def described(self) -> dict[str, Any]:
        """The system's variables as the runner names them (``component.variable``), from
        the components that can be read: for naming a spec's mistakes before it runs."""
        variables = []
        for name, path in self.components.items():
            try:
                description = _description(f"{self.origin}.components.{name}", path)
            except SpecError:
                continue
            variables += [{"name": f"{name}.{v['name']}", "causality": v["causality"],
                           "variability": v["variability"], "type": v["type"]}
                          for v in description["variables"]]
        return {"variables": variables}

    def digest(self) -> str:
        """A hash of the components' contents, the connections and the engine: what decides
        the runs."""
        h = hashlib.sha256()
        for name in sorted(self.components):
            h.update(name.encode() + b"\0" + hashlib.sha256(self.components[name].read_bytes()).digest())
        h.update(json.dumps([str(c) for c in self.connections]).encode())
        h.update(f"{self.engine}|{self.input_derivatives}".encode())
        if self.coupling_tolerance is not None:
            h.update(f"|{self.coupling_tolerance!r}".encode())
        return h.hexdigest()

    def build(self, step: float) -> Archive:
        """What the runner loads for the system at communication step `step`: the
        components and connections (native), or the container FMU. Its checksum is the
        system's digest (with the step), so that a rebuild of the same system resumes the
        same sweep."""
        descriptions = self.check()
        archive = (self._native(descriptions) if self.engine == "native"
                   else self._container(descriptions, step))
        archive.sha256 = hashlib.sha256(f"{self.digest()}|{step!r}".encode()).hexdigest()
        return archive

    # --- the engines -------------------------------------------------------------------------
    def _native(self, descriptions: dict[str, Any]) -> Archive:
        """system.json and the components' files, zipped (stored: they are zips already)."""
        order = _feed_order(self.connections, descriptions)
        layout = {
            "components": [{"name": name, "file": f"components/{name}.fmu"}
                           for name in self.components],
            "connections": [{"from": f"{c.source}.{c.output}", "to": f"{c.target}.{c.input}"}
                            for c in order],
            "input_derivatives": self.input_derivatives,
        }
        if self.coupling_tolerance is not None:
            layout["coupling_tolerance"] = self.coupling_tolerance
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
            archive.writestr("system.json", json.dumps(layout, indent=1))
            for name, path in self.components.items():
                archive.writestr(f"components/{name}.fmu", path.read_bytes())
        return Archive(buffer.getvalue(), "system.zip")

    def _container(self, descriptions: dict[str, Any], step: float) -> Archive:
        try:
            from fmu_manipulation_toolbox.assembly import AssemblyNode
        except ImportError:
            raise SpecError("system.engine", "engine = \"container\" needs "
                                             "fmu-manipulation-toolbox: pip install "
                                             "'fmusweep[container]'") from None
        with tempfile.TemporaryDirectory(prefix="fmusweep-system-") as tmp:
            directory = pathlib.Path(tmp)
            node = AssemblyNode("system.fmu", step_size=step, auto_parameter=True, auto_link=False,
                                auto_input=False, auto_output=False)
            fed = {(c.target, c.input) for c in self.connections}
            for name, path in self.components.items():
                shutil.copyfile(path, directory / f"{name}.fmu")
                node.add_fmu(f"{name}.fmu")
                for v in descriptions[name]["variables"]:
                    if v["causality"] == "output":
                        node.add_output(f"{name}.fmu", v["name"], f"{name}.{v['name']}")
                    elif v["causality"] == "input" and (name, v["name"]) not in fed:
                        node.add_input(f"{name}.{v['name']}", f"{name}.fmu", v["name"])
            for c in self.connections:
                node.add_link(f"{c.source}.fmu", c.output, f"{c.target}.fmu", c.input)
            try:
                with _toolbox_log_quiet():
                    node.make_fmu(directory)
            except Exception as e:  # the toolbox's own refusal, in its words
                raise SpecError("system", f"the container could not be built: {e}") from None
            data = (directory / "system.fmu").read_bytes()
        return Archive(data, "system.fmu")


def _component(name: str, path: object) -> None:
    where = f"system.components.{name}"
    if not NAME.match(name):
        raise SpecError(where, "a component's name is lowercase letters, digits and _, "
                               "starting with a letter (it prefixes its variables' names)")
    if not isinstance(path, str):
        raise SpecError(where, "must be the path of an FMU (a string)")


def _options(table: dict[str, Any], engines: tuple[str, ...]) -> tuple[str, int, float | None]:
    """The engine, the input derivatives and the coupling tolerance a table chooses, every
    mistake of them at once."""
    errors = Collector()
    engine = table.get("engine", "native")
    if engine not in engines:
        errors.run(lambda: refuse("system.engine", f"must be one of {', '.join(engines)}, "
                                                   f"got {engine!r}"))
        engine = "native"
    derivatives = table.get("input_derivatives", 2 if engine == "native" else 0)
    if isinstance(derivatives, bool) or derivatives not in (0, 1, 2):
        errors.run(lambda: refuse("system.input_derivatives",
                                  f"must be 0, 1 or 2, got {derivatives!r}"))
    elif engine == "container" and derivatives != 0:
        errors.run(lambda: refuse("system.input_derivatives", "the container holds inputs over "
                                  "a step: only 0 with engine = \"container\""))
    tolerance = errors.run(lambda: _coupling_tolerance(table.get("coupling_tolerance"), engine))
    errors.raise_any()
    return engine, derivatives, tolerance


def _refuse_python_written(where: str, description: dict[str, Any]) -> None:
    """A component written in Python (PythonFMU) runs Python at every step: the native
    runner, whose point is running none, refuses it by name."""
    tool = description.get("generation_tool") or ""
    if tool.startswith("PythonFMU"):
        raise SpecError(where, f"{description['model_name']} is written in Python ({tool}); the "
                               "native runner runs compiled FMUs only (an SSP file with it "
                               "runs through FMPy with [system] engine = \"fmpy\")")


# Per process: an SSP file's checksum -> the folder its components are unpacked into.
_SSP_FOLDERS: dict[str, pathlib.Path] = {}


def _unpacked_components(path: pathlib.Path, contents: SspContents) -> pathlib.Path:
    """This process's folder of the SSP file's component FMUs, each as <name>.fmu; removed
    when the process ends."""
    data = path.read_bytes()
    key = hashlib.sha256(data).hexdigest()
    folder = _SSP_FOLDERS.get(key)
    if folder is None:
        folder = pathlib.Path(tempfile.mkdtemp(prefix=f"fmusweep-ssp-{key[:12]}-"))
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            for name, member in contents.components.items():
                (folder / f"{name}.fmu").write_bytes(archive.read(member))
        _SSP_FOLDERS[key] = folder
    return folder


@atexit.register
def _remove_ssp_folders() -> None:
    for folder in _SSP_FOLDERS.values():
        shutil.rmtree(folder, ignore_errors=True)


def _coupling_tolerance(value: object, engine: str) -> float | None:
    if value is None:
        return None
    where = "system.coupling_tolerance"
    if engine != "native":
        raise SpecError(where, "only the native engine chooses its steps: not with "
                               "engine = \"container\"")
    tolerance = finite(value, where)
    if not 0 < tolerance < 1:
        raise SpecError(where, f"must be a number in (0, 1), got {tolerance}")
    return tolerance


@contextlib.contextmanager
def _toolbox_log_quiet() -> Iterator[None]:
    """The toolbox logs its progress and remarks at INFO and WARNING (a loop of connections
    is one: the loop's first component starts without its inputs' values, as in any
    co-simulation); its errors still show."""
    toolbox = logging.getLogger("fmu_manipulation_toolbox")
    level = toolbox.level
    toolbox.setLevel(logging.ERROR)
    try:
        yield
    finally:
        toolbox.setLevel(level)


def _connection(i: int, pair: object, components: dict[str, Any]) -> Connection:
    where = f"system.connections[{i}]"
    if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(p, str) for p in pair)):
        raise SpecError(where, f"must be [\"component.output\", \"component.input\"], got {pair!r}")
    ends = []
    for end in pair:
        component, dot, variable = end.partition(".")
        if not dot or not variable:
            raise SpecError(where, f"{end!r} is not component.variable")
        if component not in components:
            raise SpecError(where, f"no component {component!r} (the components: "
                                   f"{', '.join(sorted(components))})")
        ends.append((component, variable))
    (source, output), (target, input_) = ends
    return Connection(source, output, target, input_)


def _description(where: str, path: pathlib.Path) -> dict[str, Any]:
    """The component's model description, as the runner reads it (a mistake named by
    `where`)."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SpecError(where, f"cannot read {path}: {e.strerror}") from None
    if not zipfile.is_zipfile(io.BytesIO(data)):
        raise SpecError(where, f"{path} is not an FMU (not a zip archive)")
    with tempfile.TemporaryDirectory(prefix="fmusweep-description-") as directory:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            try:
                archive.extract("modelDescription.xml", directory)
            except KeyError:
                raise SpecError(where, f"{path} is not an FMU (it has no "
                                       "modelDescription.xml)") from None
        try:
            description = describe_unpacked(directory)
        except RunnerError as e:
            message = str(e).replace(f"{directory}{os.sep}", "")
            raise SpecError(where, f"{path}: {message}") from None
    if description.get("model_identifier") is None:
        raise SpecError(where, f"{path} is not an FMI 2.0 or 3.0 co-simulation FMU")
    return description


def _variable(description: dict[str, Any], component: str, name: str,
              where: str) -> dict[str, Any]:
    for v in description["variables"]:
        if v["name"] == name:
            found: dict[str, Any] = v
            return found
    raise SpecError(where, f"component {component} has no variable {name!r}")


def _feed_order(connections: list[Connection], descriptions: dict[str, Any]) -> list[Connection]:
    """The connections in an order that passes an output only after the connections that
    feed the inputs it depends on directly (there is no algebraic loop: the order exists)."""
    edges = _dependencies(connections, descriptions)
    fed = {f"{c.target}.{c.input}" for c in connections}

    def needs(c: Connection) -> set[str]:
        output = f"{c.source}.{c.output}"
        return {node for node, targets in edges.items() if output in targets} & fed

    placed: list[Connection] = []
    done: set[str] = set()
    pending = list(connections)
    while pending:
        ready = next((c for c in pending if needs(c) <= done), pending[0])
        placed.append(ready)
        done.add(f"{ready.target}.{ready.input}")
        pending.remove(ready)
    return placed


def _dependencies(connections: list[Connection], descriptions: dict[str, Any]) -> dict[str, set[str]]:
    """Edges from each variable to those that depend on it directly: a connection's output
    to its input, and a component's input to its outputs (their ModelStructure; an output
    without a dependency list depends on every input, as the standard says)."""
    edges: dict[str, set[str]] = {}
    for c in connections:
        edges.setdefault(f"{c.source}.{c.output}", set()).add(f"{c.target}.{c.input}")
    for name, description in descriptions.items():
        variables = description["variables"]
        inputs = {v["name"] for v in variables if v["causality"] == "input"}
        # By value reference, the first name (FMI 3.0's aliases share a reference).
        named: dict[int, str] = {}
        for v in variables:
            named.setdefault(v["value_reference"], v["name"])
        for output in description["output_dependencies"]:
            listed = output["dependencies"]
            depends = (inputs if listed is None
                       else {named.get(vr, "") for vr in listed} & inputs)
            for input_ in depends:
                edges.setdefault(f"{name}.{input_}", set()).add(
                    f"{name}.{named[output['value_reference']]}")
    return edges


def _algebraic_loop(connections: list[Connection], descriptions: dict[str, Any]) -> list[str] | None:
    """A cycle through the connections and the components' direct dependencies of outputs
    on inputs, as the names along it; None when there is none."""
    edges = _dependencies(connections, descriptions)
    state: dict[str, int] = {}

    def visit(node: str, trail: list[str]) -> list[str] | None:
        path = trail + [node]
        state[node] = 1
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:  # on the path: a cycle
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt, path)
                if found:
                    return found
        state[node] = 2
        return None

    for node in sorted(edges):
        if node not in state:
            found = visit(node, [])
            if found:
                return found
    return None


def open_target(system: System | None, fmu: str | os.PathLike[str] | None,
                spec_fmu: str | os.PathLike[str] | None,
                step: float) -> tuple[Archive, NativeRunner, dict[str, Any]]:
    """What a sweep or a fit runs, for the checks before anything runs: the FMU the caller
    names, else the spec's [system] (built for communication step `step`), else the spec's
    FMU or $FMUSWEEP_FMU. Its bytes, this process's runner for it, and its description."""
    if system is not None and fmu is None:
        target = system.build(step)
        return (target, *load_system(target))
    return open_for_checks(fmu, spec_fmu)


def load_system(target: Archive) -> tuple[NativeRunner, dict[str, Any]]:
    """The runner of a coupled system and its description; a system that does not load (a
    component that cannot be loaded, say) is refused as a whole."""
    try:
        local = local_runner(target)
        local.configure(new_plan(0.0, 1.0, 1.0))
        loaded = local.check([], [[]])[0]
    except RunnerError as e:
        raise SpecError("system", f"the system does not load: {e}") from None
    if loaded["status"] != "ok":
        raise SpecError("system", f"the system does not load: {loaded['message']}")
    return local, local.describe()
