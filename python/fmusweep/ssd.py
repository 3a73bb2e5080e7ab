"""SSP files (SSP 1.0) read natively: the system structure (``SystemStructure.ssd``), its
components' FMUs, its connections, its parameter values (SSV files or inline parameter
sets, bound to a component or to the system) and its default experiment. What this
gives becomes the same coupled system a spec's ``[system]`` table describes
(``fmusweep.system``), run by the native runner.

What the native runner cannot run is refused here, by what it is: nested systems, a
connection to the system's own connectors, a connection that transforms its value, a
parameter mapping, a component that is not an FMU, a parameter given as an enumeration
item's name or a string. FMPy's SSP path (``[system] engine = "fmpy"``) remains for those.
"""

from __future__ import annotations

import io
import pathlib
import posixpath
import zipfile
from dataclasses import dataclass, field
from typing import Any
from xml.etree import ElementTree

from .errors import SpecError

__all__ = ["SspContents", "read_ssp"]

NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues"}
FMU_TYPE = "application/x-fmu-sharedlibrary"
PARAMETER_SET_TYPE = "application/x-ssp-parameter-set"
# The ssd elements that change what a connection or binding means, which the runner does not apply.
TRANSFORMS = ("LinearTransformation", "BooleanMappingTransformation",
              "IntegerMappingTransformation", "EnumerationMappingTransformation")


@dataclass(frozen=True)
class SspConnection:
    source: str   # component
    output: str
    target: str   # component
    input: str


@dataclass
class SspContents:
    """An SSP file's system: each component's FMU (its path in the archive), the
    connections, the parameter values by ``component.variable`` and the default
    experiment's start and stop times (None where it gives none)."""
    components: dict[str, str]
    connections: list[SspConnection]
    parameters: dict[str, float | bool] = field(default_factory=dict)
    start: float | None = None
    stop: float | None = None


def read_ssp(path: pathlib.Path) -> SspContents:
    """The system of the SSP file at `path`; every construct the native runner cannot run
    is refused by name (field ``ssp``)."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SpecError("ssp", f"cannot read {path}: {e.strerror}") from None
    if not zipfile.is_zipfile(io.BytesIO(data)):
        raise SpecError("ssp", f"{path} is not an SSP file (not a zip archive)")
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return _Reader(path, archive).read()


class _Reader:
    def __init__(self, path: pathlib.Path, archive: zipfile.ZipFile):
        self.path = path
        self.archive = archive
        self.names = set(archive.namelist())

    def refuse(self, what: str) -> SpecError:
        return SpecError("ssp", f"{self.path.name}: {what}")

    def xml(self, member: str) -> ElementTree.Element:
        if member not in self.names:
            raise self.refuse(f"the archive holds no {member}")
        try:
            return ElementTree.fromstring(self.archive.read(member))
        except ElementTree.ParseError as e:
            raise self.refuse(f"{member} is not well-formed XML: {e}") from None

    def read(self) -> SspContents:
        root = self.xml("SystemStructure.ssd")
        system = root.find("ssd:System", NS)
        if system is None:
            raise self.refuse("SystemStructure.ssd has no System")
        contents = SspContents(self.components(system), self.connections(system))
        for element in system.findall("ssd:Elements/ssd:Component", NS):
            self.bind(element.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS),
                      contents, element.get("name", ""))
        self.bind(system.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS), contents, None)
        experiment = root.find("ssd:DefaultExperiment", NS)
        if experiment is not None:
            contents.start = self.number(experiment, "startTime")
            contents.stop = self.number(experiment, "stopTime")
        return contents

    def number(self, element: ElementTree.Element, name: str) -> float | None:
        text = element.get(name)
        if text is None:
            return None
        try:
            return float(text)
        except ValueError:
            raise self.refuse(f"DefaultExperiment {name}={text!r} is not a number") from None

    # --- the structure -------------------------------------------------------------------
    def components(self, system: ElementTree.Element) -> dict[str, str]:
        elements = system.find("ssd:Elements", NS)
        found: dict[str, str] = {}
        for element in (elements if elements is not None else []):
            kind = element.tag.rpartition("}")[2]
            name = element.get("name", "")
            if kind == "System":
                raise self.refuse(f"{name!r} is a nested system; the native runner runs one "
                                  "level of components")
            if kind != "Component":
                raise self.refuse(f"the system holds a {kind} ({name!r}); the native runner "
                                  "runs FMU components only")
            if not name or "." in name or name in found:
                raise self.refuse(f"a component's name must be present, unique and without a "
                                  f"dot (it prefixes its variables' names), got {name!r}")
            if element.get("type", FMU_TYPE) != FMU_TYPE:
                raise self.refuse(f"component {name} is a {element.get('type')}, not an FMU")
            source = element.get("source", "")
            member = posixpath.normpath(source) if source and ":" not in source else None
            if member is None or member not in self.names:
                raise self.refuse(f"component {name}: its source {source!r} is not a file "
                                  "inside the archive")
            found[name] = member
        if not found:
            raise self.refuse("the system has no component")
        return found

    def connections(self, system: ElementTree.Element) -> list[SspConnection]:
        found = []
        for i, c in enumerate(system.findall("ssd:Connections/ssd:Connection", NS)):
            ends = [c.get(k) for k in ("startElement", "startConnector", "endElement", "endConnector")]
            source, output, target, input_ = ends
            if source is None or target is None:
                own = output if source is None else input_
                raise self.refuse(f"connection {i} joins the system's own connector {own!r}; "
                                  "the native runner joins components to components")
            transform = next((t for t in TRANSFORMS if c.find(f"ssd:{t}", NS) is not None), None)
            if transform is not None:
                raise self.refuse(f"connection {i} ({source}.{output} → {target}.{input_}) "
                                  f"applies a {transform}, which the native runner does not")
            if output is None or input_ is None:
                raise self.refuse(f"connection {i} lacks a connector name")
            found.append(SspConnection(source, output, target, input_))
        return found

    # --- parameter values ----------------------------------------------------------------
    def bind(self, bindings: list[ElementTree.Element], contents: SspContents,
             component: str | None) -> None:
        """Each binding's values into `contents.parameters`, named component.variable: a
        component's binding names its own variables (a leading "component." allowed), the
        system's names them with the component; a binding's prefix comes first."""
        for binding in bindings:
            if binding.get("type", PARAMETER_SET_TYPE) != PARAMETER_SET_TYPE:
                raise self.refuse(f"a parameter binding of type {binding.get('type')}")
            if binding.find("ssd:ParameterMapping", NS) is not None:
                raise self.refuse("a parameter binding with a ParameterMapping, which the "
                                  "native runner does not apply")
            prefix = binding.get("prefix", "")
            for name, value in self.parameter_set(binding).items():
                full = prefix + name
                if component is not None:
                    variable = full.removeprefix(f"{component}.")
                    contents.parameters[f"{component}.{variable}"] = value
                    continue
                owner, dot, _ = full.partition(".")
                if not dot or owner not in contents.components:
                    raise self.refuse(f"the system's parameter {full!r} is not "
                                      "component.variable of a component of the system")
                contents.parameters[full] = value

    def parameter_set(self, binding: ElementTree.Element) -> dict[str, float | bool]:
        source = binding.get("source")
        if source is not None:
            where = posixpath.normpath(source)
            values = self.xml(where)
        else:
            where = "an inline parameter set"
            inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            if inline is None:
                return {}
            values = inline
        found: dict[str, float | bool] = {}
        for parameter in values.findall("ssv:Parameters/ssv:Parameter", NS):
            found[parameter.get("name", "")] = self.value(parameter, where)
        return found

    def value(self, parameter: ElementTree.Element, where: str) -> float | bool:
        name = parameter.get("name", "")
        for child in parameter:
            kind = child.tag.rpartition("}")[2]
            text = child.get("value")
            if kind in ("Real", "Integer") and text is not None:
                try:
                    number: Any = float(text) if kind == "Real" else int(text)
                except ValueError:
                    raise self.refuse(f"{where}: {name} = {text!r} is not a {kind}") from None
                return float(number)
            if kind == "Boolean" and text in ("true", "false", "1", "0"):
                return text in ("true", "1")
            if kind in ("Real", "Integer", "Boolean"):
                raise self.refuse(f"{where}: {name} = {text!r} is not a {kind}")
            if kind in ("Enumeration", "String", "Binary"):
                raise self.refuse(f"{where}: {name} is given as a {kind}; the native runner "
                                  "sets numbers and Booleans (give an enumeration its number "
                                  "as an Integer)")
        raise self.refuse(f"{where}: parameter {name!r} has no value")
