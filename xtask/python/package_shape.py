"""What `cargo xtask tidy` needs to know of a Python package's shape, as lines of text it
judges by the same rules as the crates (layers, circles, lengths): every module with its
file and length, every import of a module of the package (those under TYPE_CHECKING and
inside functions too) with its line, every function with its length.

Usage: package_shape.py PACKAGE_DIR. Prints, one fact a line, tab-separated:
  module NAME PATH LINES
  import NAME LINE TARGET
  function PATH LINE NAME LINES
Modules are named from the package: "cli", "fitting.run", "__init__" for the package's
own, "fitting" for a subpackage's."""

from __future__ import annotations

import ast
import pathlib
import sys


def module_name(package: pathlib.Path, path: pathlib.Path) -> str:
    parts = list(path.relative_to(package).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1] or ["__init__"]
    return ".".join(parts)


def imports(tree: ast.AST, name: str, is_package: bool, package: str,
            known: set[str]) -> list[tuple[int, str]]:
    """(line, module) for each module of the package this module imports, wherever the
    import stands."""
    own = [] if name == "__init__" else name.split(".")
    base = own if is_package else own[:-1]
    found: list[tuple[int, str]] = []
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
            subs = [s for s in (".".join(target + [a.name]) for a in node.names) if s in known]
            found += [(node.lineno, s) for s in subs or ([stem] if stem in known else [])]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                target = ".".join(parts[1:]) or "__init__"
                if parts[0] == package and target in known:
                    found.append((node.lineno, target))
    return [(line, target) for line, target in found if target != name]


def main(package_dir: str) -> int:
    package = pathlib.Path(package_dir)
    files = sorted(package.rglob("*.py"))
    names = {module_name(package, f): f for f in files}
    for name, path in names.items():
        text = path.read_text()
        shown = path.as_posix()
        tree = ast.parse(text, filename=shown)
        print(f"module\t{name}\t{shown}\t{len(text.splitlines())}")
        for line, target in imports(tree, name, path.name == "__init__.py", package.name,
                                    set(names)):
            print(f"import\t{name}\t{line}\t{target}")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                print(f"function\t{shown}\t{node.lineno}\t{node.name}\t{length}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
