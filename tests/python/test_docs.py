"""The repository describes itself: no document or source points outside it (to files
beside the clone, or to a tracker), every relative link in the Markdown documents
resolves to a file in the repository, and the README's example prints what it says."""

import pathlib
import re
import subprocess
import sys

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


NUMBER = re.compile(r"\d+(?:[.,\u2009\u202f ]\d+)*(?:e[-+]?\d+)?")


def numbers(text):
    """The numbers of `text`, digit groups joined (1 234.5 is 1234.5)."""
    return {re.sub(r"[,\u2009\u202f ]", "", n) for n in NUMBER.findall(text)}


def test_quoted_figures_match_their_reports():
    """A document quotes a measured figure as a link to the report a command wrote, the
    figure as the link's text: every number in that text must be in the report."""
    quote = re.compile(r"\[([^\]]*\d[^\]]*)\]\(([^)#\s]+)\)")
    reports = (ROOT / "docs/bench").resolve()
    checked, wrong = 0, []
    for doc in (p for p in tracked() if p.suffix == ".md"):
        for text, target in quote.findall(doc.read_text()):
            report = (doc.parent / target).resolve()
            if report.parent != reports:
                continue
            checked += 1
            missing = numbers(text) - numbers(report.read_text())
            if missing:
                wrong.append(f"{doc.relative_to(ROOT)}: [{text}] not in {target}: {sorted(missing)}")
    assert checked > 0, "no figure is quoted from a report"
    assert not wrong, "\n".join(wrong)


def test_the_readme_fmpy_example_prints_what_it_says(fmu_path):
    """The README's FMPy snippet, run as written (on the FMU under test): every default is
    the paper's case 1, so the run moves and prints the published values."""
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## Using the FMU from FMPy", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    promised = re.search(r"# ([-\d.]+) ([-\d.]+)\s*$", code.strip()).groups()
    code = code.replace('"target/fmu/CyclicMechanism.fmu"', repr(str(fmu_path)))
    printed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout.split()
    assert [f"{float(v):.8f}" for v in printed] == list(promised), (printed, promised)
