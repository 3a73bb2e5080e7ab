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
import dataclasses
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

from .errors import Collector, SpecError, SpecErrors
from .fmu import Archive, local_runner
from .native import NativeRunner, RunnerError, describe_unpacked
from .records import new_plan
from .ssd import SspContents

__all__ = ["System", "Connection", "load_system"]


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

    # --- the spec's table ---------------------------------------------------------------
    @staticmethod
    def from_table(table: Any, base_dir: pathlib.Path) -> System | None:
        """The system of a [system] table (``schema.sweep.SystemTable``), or of what was
        read of one with mistakes (its options' defaults where they are wrong, its
        connections that were read), so that its components and connections are checked in
        the same pass; None without components."""
        components = table.get("components")
        if not components:
            return None
        connections = [Connection(source, output, target, input_)
                       for (source, output), (target, input_)
                       in [c for c in table.get("connections") or [] if c is not None]
                       if source in components and target in components]
        engine = table.get("engine") or "native"
        derivatives = table.get("input_derivatives")
        return System({name: base_dir / path for name, path in components.items()},
                      connections, engine,
                      (2 if engine == "native" else 0) if derivatives is None else derivatives,
                      table.get("coupling_tolerance"))

    @staticmethod
    def from_ssp(path: pathlib.Path, contents: SspContents, table: Any) -> System:
        """The system an SSP file describes (`contents`, read from `path`), its components
        unpacked into this process's folder for them; `table` is the spec's [system]
        beside it (``schema.sweep.SspSystemOptions``), which may only choose how it runs."""
        engine = table.engine if table is not None else "native"
        derivatives = table.input_derivatives if table is not None else None
        tolerance = table.coupling_tolerance if table is not None else None
        directory = _unpacked_components(path, contents)
        connections = [Connection(c.source, c.output, c.target, c.input)
                       for c in contents.connections]
        for i, c in enumerate(connections):
            for component in (c.source, c.target):
                if component not in contents.components:
                    raise SpecError("ssp", f"{path.name}: connection {i} ({c}) names no component "
                                           f"of the system ({', '.join(contents.components)})")
        return System({name: directory / f"{name}.fmu" for name in contents.components},
                      connections, engine,
                      (2 if engine == "native" else 0) if derivatives is None else derivatives,
                      tolerance, origin="ssp")

    # --- checks against the components -------------------------------------------------
    def check(self) -> tuple[dict[str, Any], list[Connection], list[SpecError]]:
        """Each component's model description (those that can be read), the connections
        that hold against them, and every mistake of the components and connections."""
        errors = Collector()
        descriptions = {}
        for name, path in self.components.items():
            where = f"{self.origin}.components.{name}"
            description = errors.run(lambda: _description(where, path))
            if description is not None:
                descriptions[name] = description
                if self.engine == "native":
                    errors.run(lambda: _refuse_python_written(where, description))
        fed: dict[tuple[str, str], int] = {}
        good = [c for i, c in enumerate(self.connections)
                if c.source in descriptions and c.target in descriptions
                and errors.run(lambda: self._check_connection(i, c, descriptions, fed))]
        loop = _algebraic_loop(good, descriptions)
        if loop:
            errors.run(lambda: _refuse(f"{self.origin}.connections", "an algebraic loop (each "
                                       "output depends directly on the input before it): "
                                       + " → ".join(loop)))
            good = []
        return descriptions, good, errors.errors

    def _check_connection(self, i: int, c: Connection, descriptions: dict[str, Any],
                          fed: dict[tuple[str, str], int]) -> bool:
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
        return True

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
        descriptions, _, errors = self.check()
        if errors:
            raise errors[0] if len(errors) == 1 else SpecErrors(errors)
        return self._built(descriptions, step)

    def _built(self, descriptions: dict[str, Any], step: float) -> Archive:
        archive = (self._native(descriptions) if self.engine == "native"
                   else self._container(descriptions, step))
        archive.sha256 = hashlib.sha256(f"{self.digest()}|{step!r}".encode()).hexdigest()
        return archive

    def opened(self, step: float, errors: list[SpecError]
               ) -> tuple[Archive, NativeRunner, dict[str, Any]] | None:
        """The system built and loaded in this process's runner, for the checks before
        anything runs, every mistake of it added to `errors`: of its components and
        connections, and the runner's refusals of its options (the coupling tolerance's rule
        is the runner's). Built with the connections that hold, so that the runner's
        refusals come in the same pass; None where it cannot be loaded."""
        descriptions, good, found = self.check()
        errors += found
        if len(descriptions) < len(self.components):
            return None
        built = dataclasses.replace(self, connections=good)
        try:
            archive = built._built(descriptions, step)
            local, description = load_system(archive)
        except SpecError as e:
            if not found or e.field != "system":
                errors.append(e)
            if built.coupling_tolerance is None or e.field == "system":
                return None
            # The rest is checked against the system as it runs without the option.
            try:
                archive = dataclasses.replace(built, coupling_tolerance=None)._built(
                    descriptions, step)
                local, description = load_system(archive)
            except SpecError:
                return None
        return archive, local, description

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


def _refuse(where: str, rule: str) -> None:
    raise SpecError(where, rule)


def load_system(target: Archive) -> tuple[NativeRunner, dict[str, Any]]:
    """The runner of a coupled system and its description; a system that does not load (a
    component that cannot be loaded, say) is refused as a whole."""
    try:
        local = local_runner(target)
        local.configure(new_plan(0.0, 1.0, 1.0))
        loaded = local.check([], [[]])[0]
    except RunnerError as e:
        raise _refused(str(e)) from None
    if loaded["status"] != "ok":
        raise _refused(loaded["message"])
    return local, local.describe()


# A refusal of a [system] field in the runner's words: "system.FIELD: rule".
_FIELD_REFUSAL = re.compile(r"(system\.[a-z_]+(?:\.[A-Za-z_][A-Za-z0-9_]*)?): (.*)", re.S)


def _refused(message: str) -> SpecError:
    """The runner's refusal of a system: by the field it names (a rule the runner holds,
    such as the coupling tolerance's), else of the system as a whole."""
    said = _FIELD_REFUSAL.search(message)
    if said is not None:
        return SpecError(said.group(1), said.group(2).strip())
    return SpecError("system", f"the system does not load: {message}")
