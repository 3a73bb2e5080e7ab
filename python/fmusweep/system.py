"""Coupled systems named in a spec's ``[system]`` table: components (FMI 2.0 co-simulation
FMUs) and connections from an output of one to an input of another::

    [system]
    components = { motor = "DcMotor.fmu", mechanism = "CyclicMechanism.fmu" }
    connections = [["motor.torque", "mechanism.M_m"], ["mechanism.omega1", "motor.omega"]]

The system runs as one FMU in the native runner, like any other: a container FMU
(fmu-manipulation-toolbox's, whose compiled master steps the components at the
scenario's communication step, holding each input over the step) built once per sweep.
Every parameter of a component is ``component.parameter``, every output
``component.output``, every input left unconnected ``component.input``; the sweep's
designs, metrics and series address them so. Everything is checked before anything runs:
names, files, each connection's ends and types, inputs fed twice, algebraic loops.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import logging
import pathlib
import re
import shutil
import tempfile
import zipfile
from dataclasses import dataclass

from .errors import SpecError
from .fmu import Archive, local_runner
from .native import RunnerError

__all__ = ["System", "load_system"]

NAME = re.compile(r"[a-z][a-z0-9_]*\Z")


@dataclass(frozen=True)
class Connection:
    source: str   # component
    output: str
    target: str   # component
    input: str

    def __str__(self):
        return f"{self.source}.{self.output} → {self.target}.{self.input}"


@dataclass
class System:
    components: dict[str, pathlib.Path]
    connections: list[Connection]

    # --- the spec's fields ---------------------------------------------------------------
    @staticmethod
    def of(table, base_dir: pathlib.Path) -> "System":
        if not isinstance(table, dict):
            raise SpecError("system", "must be a table with components and connections")
        unknown = sorted(set(table) - {"components", "connections"})
        if unknown:
            raise SpecError(f"system.{unknown[0]}", "unknown field; expected components, connections")
        components = table.get("components")
        if not isinstance(components, dict) or not components:
            raise SpecError("system.components", "must name at least one component: name = \"file.fmu\"")
        paths = {}
        for name, path in components.items():
            where = f"system.components.{name}"
            if not NAME.match(name):
                raise SpecError(where, "a component's name is lowercase letters, digits and _, "
                                       "starting with a letter (it prefixes its variables' names)")
            if not isinstance(path, str):
                raise SpecError(where, "must be the path of an FMU (a string)")
            paths[name] = base_dir / path
        connections = table.get("connections", [])
        if not isinstance(connections, list):
            raise SpecError("system.connections", "must be a list of [\"component.output\", "
                                                  "\"component.input\"] pairs")
        parsed = [_connection(i, c, paths) for i, c in enumerate(connections)]
        return System(paths, parsed)

    # --- checks against the components -------------------------------------------------
    def check(self) -> dict:
        """Each component's model description; each connection checked against them."""
        descriptions = {name: _description(name, path) for name, path in self.components.items()}
        fed = {}
        for i, c in enumerate(self.connections):
            where = f"system.connections[{i}]"
            source = _variable(descriptions[c.source], c.source, c.output, where)
            target = _variable(descriptions[c.target], c.target, c.input, where)
            if source.causality != "output":
                raise SpecError(where, f"{c.source}.{c.output} has causality {source.causality}; "
                                       "a connection starts at an output")
            if target.causality != "input":
                raise SpecError(where, f"{c.target}.{c.input} has causality {target.causality}; "
                                       "a connection ends at an input")
            if source.type != target.type:
                raise SpecError(where, f"{c}: a {source.type} output cannot feed a {target.type} input")
            if (c.target, c.input) in fed:
                raise SpecError(where, f"{c.target}.{c.input} is fed twice (also by connection "
                                       f"{fed[(c.target, c.input)]})")
            fed[(c.target, c.input)] = i
        loop = _algebraic_loop(self.connections, descriptions)
        if loop:
            raise SpecError("system.connections", "an algebraic loop (each output depends directly "
                                                  "on the input before it): " + " → ".join(loop))
        return descriptions

    def digest(self) -> str:
        """A hash of the components' contents and the connections: what decides the runs."""
        h = hashlib.sha256()
        for name in sorted(self.components):
            h.update(name.encode() + b"\0" + hashlib.sha256(self.components[name].read_bytes()).digest())
        h.update(json.dumps([str(c) for c in self.connections]).encode())
        return h.hexdigest()

    # --- the container ---------------------------------------------------------------------
    def build(self, step: float) -> Archive:
        """The container FMU of the system at communication step `step`. Its checksum is
        the system's digest (with the step), so that a rebuild of the same system resumes
        the same sweep."""
        descriptions = self.check()
        from fmu_manipulation_toolbox.assembly import AssemblyNode
        with tempfile.TemporaryDirectory(prefix="fmusweep-system-") as tmp:
            directory = pathlib.Path(tmp)
            node = AssemblyNode("system.fmu", step_size=step, auto_parameter=True, auto_link=False,
                                auto_input=False, auto_output=False)
            fed = {(c.target, c.input) for c in self.connections}
            for name, path in self.components.items():
                shutil.copyfile(path, directory / f"{name}.fmu")
                node.add_fmu(f"{name}.fmu")
                for v in descriptions[name].modelVariables:
                    if v.causality == "output":
                        node.add_output(f"{name}.fmu", v.name, f"{name}.{v.name}")
                    elif v.causality == "input" and (name, v.name) not in fed:
                        node.add_input(f"{name}.{v.name}", f"{name}.fmu", v.name)
            for c in self.connections:
                node.add_link(f"{c.source}.fmu", c.output, f"{c.target}.fmu", c.input)
            try:
                with _toolbox_log_quiet():
                    node.make_fmu(directory)
            except Exception as e:  # the toolbox's own refusal, in its words
                raise SpecError("system", f"the container could not be built: {e}") from None
            data = (directory / "system.fmu").read_bytes()
        archive = Archive(data, "system.fmu")
        archive.sha256 = hashlib.sha256(f"{self.digest()}|{step!r}".encode()).hexdigest()
        return archive


@contextlib.contextmanager
def _toolbox_log_quiet():
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


def _connection(i: int, pair, components: dict) -> Connection:
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


def _description(name: str, path: pathlib.Path):
    import fmpy
    where = f"system.components.{name}"
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SpecError(where, f"cannot read {path}: {e.strerror}") from None
    if not zipfile.is_zipfile(io.BytesIO(data)):
        raise SpecError(where, f"{path} is not an FMU (not a zip archive)")
    try:
        description = fmpy.read_model_description(str(path), validate=False)
    except Exception as e:
        raise SpecError(where, f"{path}: its modelDescription.xml cannot be read: {e}") from None
    if description.fmiVersion != "2.0" or description.coSimulation is None:
        raise SpecError(where, f"{path} is not an FMI 2.0 co-simulation FMU")
    return description


def _variable(description, component: str, name: str, where: str):
    for v in description.modelVariables:
        if v.name == name:
            return v
    raise SpecError(where, f"component {component} has no variable {name!r}")


def _algebraic_loop(connections: list[Connection], descriptions: dict) -> list[str] | None:
    """A cycle through the connections and the components' direct dependencies of outputs
    on inputs (their ModelStructure; an output without a dependency list depends on every
    input, as the standard says), as the names along it; None when there is none."""
    edges: dict[str, set[str]] = {}
    for c in connections:
        edges.setdefault(f"{c.source}.{c.output}", set()).add(f"{c.target}.{c.input}")
    for name, description in descriptions.items():
        inputs = {v.name for v in description.modelVariables if v.causality == "input"}
        for unknown in description.outputs:
            depends = (inputs if unknown.dependencies is None
                       else {d.name for d in unknown.dependencies} & inputs)
            for input_ in depends:
                edges.setdefault(f"{name}.{input_}", set()).add(f"{name}.{unknown.variable.name}")
    state: dict[str, int] = {}

    def visit(node, trail):
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


def load_system(target: Archive):
    """The runner of a coupled system's container and its description; a system that
    does not load (a component the container cannot load, say) is refused as a whole."""
    try:
        local = local_runner(target)
        local.configure({"start": 0.0, "stop": 1.0, "step": 1.0, "tolerance": None, "fixed": {},
                         "inputs": {}, "metrics": [], "series": None, "timeout_s": None})
        loaded = local.check([], [[]])[0]
    except RunnerError as e:
        raise SpecError("system", f"the system does not load: {e}") from None
    if loaded["status"] != "ok":
        raise SpecError("system", f"the system does not load: {loaded['message']}")
    return local, local.describe()
