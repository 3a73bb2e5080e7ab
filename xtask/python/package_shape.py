"""The shape of a Python package, for `cargo xtask tidy`: every import counted (those under
TYPE_CHECKING and inside functions too), none from a layer above its module's, no
modules importing each other round a circle, no file longer than MAX_FILE_LINES and no
function longer than MAX_FUNCTION_LINES. Prints one problem per line.

Usage: package_shape.py PACKAGE_DIR LAYERS_JSON (a list of layers, top down, each a list
of modules named from the package: "cli", "fitting.run", "__init__" for the package's
own, "fitting" for a subpackage's)."""

from __future__ import annotations

import ast
import json
import pathlib
import sys

MAX_FILE_LINES = 700
MAX_FUNCTION_LINES = 80


def module_name(package: pathlib.Path, path: pathlib.Path) -> str:
    parts = list(path.relative_to(package).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1] or ["__init__"]
    return ".".join(parts)


def imports(tree: ast.AST, name: str, is_package: bool, package: str,
            known: set[str]) -> set[str]:
    """The package's modules this module imports, wherever the import stands."""
    own = [] if name == "__init__" else name.split(".")
    base = own if is_package else own[:-1]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                parent = base[:len(base) - (node.level - 1)] if node.level > 1 else base
                target = parent + (node.module.split(".") if node.module else [])
            elif node.module and node.module.split(".")[0] == package:
                target = node.module.split(".")[1:]
            else:
                continue
            stem = ".".join(target) or "__init__"
            subs = [".".join(target + [a.name]) for a in node.names]
            found.update(s for s in subs if s in known)
            if not any(s in known for s in subs) and stem in known:
                found.add(stem)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == package:
                    target = ".".join(parts[1:]) or "__init__"
                    if target in known:
                        found.add(target)
    found.discard(name)
    return found


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    def reach(start: str) -> set[str]:
        seen: set[str] = set()
        todo = [start]
        while todo:
            for nxt in graph.get(todo.pop(), ()):
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        return seen
    reaches = {m: reach(m) for m in graph}
    found: list[list[str]] = []
    for m in sorted(graph):
        circle = sorted(o for o in reaches[m] if m in reaches.get(o, set()))
        if len(circle) > 1 and circle not in found:
            found.append(circle)
    return found


def main(package_dir: str, layers_json: str) -> int:
    package = pathlib.Path(package_dir)
    layers: list[list[str]] = json.loads(layers_json)
    rank = {m: i for i, layer in enumerate(layers) for m in layer}
    files = sorted(package.rglob("*.py"))
    names = {module_name(package, f): f for f in files}
    problems: list[str] = []
    graph: dict[str, set[str]] = {}
    for name, path in names.items():
        text = path.read_text()
        shown = path.as_posix()
        tree = ast.parse(text, filename=shown)
        lines = len(text.splitlines())
        if lines > MAX_FILE_LINES:
            problems.append(f"{shown}: {lines} lines, more than {MAX_FILE_LINES}")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    problems.append(f"{shown}:{node.lineno}: function {node.name} is {length} "
                                    f"lines, more than {MAX_FUNCTION_LINES}")
        if name not in rank:
            problems.append(f"{shown}: module `{name}` has no place in its layer table")
            continue
        graph[name] = imports(tree, name, path.name == "__init__.py", package.name, set(names))
        for target in sorted(graph[name]):
            if rank.get(target, len(layers)) < rank[name]:
                problems.append(f"{shown}: `{name}` imports from `{target}`, a layer above it")
    for circle in circles(graph):
        problems.append(f"{package_dir}: modules import each other round a circle: "
                        f"{', '.join(circle)}")
    for problem in problems:
        print(problem)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
