"""The repository describes itself: no document or source points outside it (to files
beside the clone, or to a tracker), and every relative link in the Markdown documents
resolves to a file in the repository."""

import pathlib
import re
import subprocess

from conftest import ROOT

TEXT = (".md", ".rs", ".py", ".toml", ".html", ".txt")


def tracked():
    names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    return [ROOT / n for n in names if n.endswith(TEXT)]


def test_nothing_points_outside_the_repository():
    outside = re.compile(r"\.\./shared|SPEC\.md|\b[Ii]ssue #?\d")
    found = [f"{p.relative_to(ROOT)}:{i}: {line.strip()}"
             for p in tracked() if p.name != "test_docs.py"
             for i, line in enumerate(p.read_text(errors="replace").splitlines(), 1)
             if outside.search(line)]
    assert not found, "\n".join(found)


def test_every_relative_link_resolves():
    link = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
    broken = []
    for doc in (p for p in tracked() if p.suffix == ".md"):
        for target in link.findall(doc.read_text()):
            if re.match(r"[a-z]+:", target):
                continue  # an absolute URL
            if not (doc.parent / target).exists():
                broken.append(f"{doc.relative_to(ROOT)} -> {target}")
    assert not broken, broken
    assert (ROOT / "docs/model.md").exists()
