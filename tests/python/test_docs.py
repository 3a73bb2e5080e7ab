"""The repository describes itself: no document or source points outside it (to files
beside the clone, or to a tracker), every relative link in the Markdown documents
resolves to a file in the repository, and the README's example prints what it says."""

import pathlib
import re
import subprocess
import sys

import pytest
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
    link = re.compile(r"\]\(([^)#\s]+)(?:#[^)\s]*)?(?:\s+\"[^\"]*\")?\)")
    broken = []
    for doc in (p for p in tracked() if p.suffix == ".md"):
        for target in link.findall(doc.read_text()):
            if re.match(r"[a-z]+:", target):
                continue  # an absolute URL
            if not (doc.parent / target).exists():
                broken.append(f"{doc.relative_to(ROOT)} -> {target}")
    assert not broken, broken
    assert (ROOT / "docs/model.md").exists()


NUMBER = re.compile(r"[-−+]?\d+(?:[,\u2009\u202f ]\d{3})*(?:\.\d+)?(?:e[-+]?\d+)?")


def values(text):
    """The numbers of `text` as printed (digit groups joined: 1 234.5 is 1234.5)."""
    return [re.sub(r"[,\u2009\u202f ]", "", n).replace("−", "-") for n in NUMBER.findall(text)]


def printed_unit(number):
    """Half of one unit in the last printed digit of `number`: how far a figure rounded to
    that many digits may lie from the report's."""
    mantissa, _, exponent = number.lower().partition("e")
    decimals = len(mantissa.split(".", 1)[1]) if "." in mantissa else 0
    return 0.5 * 10.0 ** (int(exponent or 0) - decimals)


def agrees(quoted, printed):
    """A quoted figure agrees with the report's when it is the report's, rounded to the
    quote's printed precision (never more digits than the report prints)."""
    if printed_unit(quoted) < printed_unit(printed):
        return quoted == printed
    return abs(float(quoted) - float(printed)) <= printed_unit(quoted) * (1 + 1e-9)


QUOTE = re.compile(r"\[([^\]]*\d[^\]]*)\]\(([^)\s#]+)(?:#[^)\s]*)?(?:\s+\"([^\"]*)\")?\)")
REPORTS = (ROOT / "docs/bench").resolve()


def documents():
    """README.md and docs/*.md: what a user reads (the reports themselves are written)."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def report_rows(report, label):
    """The lines of `report` its quote's label names: a label is fragments joined by " · ",
    each a whole cell of a table row or, where no row has them all, a part of a line of
    prose."""
    fragments = [f.strip() for f in label.split(" · ")]
    lines = report.read_text().splitlines()
    rows = [line for line in lines if line.startswith("|")
            and all(f in [c.strip() for c in line.strip().strip("|").split("|")] for f in fragments)]
    return rows or [line for line in lines if not line.startswith("|")
                    and all(f in line for f in fragments)]


def quotes():
    """Every quote of a report: (document, line, figures' text, report, label)."""
    for doc in documents():
        for i, line in enumerate(doc.read_text().splitlines(), 1):
            for text, target, label in QUOTE.findall(line):
                report = (doc.parent / target).resolve()
                if report.parent == REPORTS and report.suffix == ".md":
                    yield doc.relative_to(ROOT), i, text, report, label


def test_quoted_figures_match_their_report_rows():
    """A document quotes a measured figure as a link to the report a command wrote, the
    figure as the link's text and, as its title, the label of the row it comes from: the
    label names exactly one row, and every number of the quote is that row's, to the
    quote's printed precision."""
    checked, wrong = 0, []
    for doc, i, text, report, label in quotes():
        checked += 1
        where = f"{doc}:{i}: [{text}]({report.name})"
        if not report.exists():
            wrong.append(f"{where}: no such report")
            continue
        if not label:
            wrong.append(f"{where}: no label (the link's title) names the report's row")
            continue
        rows = report_rows(report, label)
        if len(rows) != 1:
            wrong.append(f"{where}: \"{label}\" names {len(rows)} rows of {report.name}, not one")
            continue
        row = values(rows[0])
        missing = [v for v in values(text) if not any(agrees(v, r) for r in row)]
        if missing:
            wrong.append(f"{where}: {missing} not in the row \"{rows[0].strip()}\"")
    assert checked > 20, f"only {checked} figures are quoted from reports"
    assert not wrong, "\n".join(wrong)


def test_every_quoted_report_names_the_commit_and_machine_it_measured():
    """A figure is worth what its provenance is: each report a document quotes says the
    machine and the commit of the build it measured (instructions.md, a row per build)."""
    quoted = {report for _, _, _, report, _ in quotes() if report.exists()}
    assert quoted
    unnamed = [r.name for r in sorted(quoted)
               if not (re.search(r"^Machine: .*commit [0-9a-f]{7}", r.read_text(), re.M)
                       or re.search(r"^\| [0-9a-f]{7} \|", r.read_text(), re.M))]
    assert not unnamed, f"reports that do not say what they measured: {unnamed}"


MEASURED = re.compile(
    r"(?<![\w.\-])(?:\d\.\d+e[-+]?\d+"
    r"|\d+(?:[,\u2009\u202f ]\d{3})*(?:\.\d+)?\s?(?:%|×(?!\s?\d)|ns\b|µs\b|ms\b|s\b|MiB\b|MB\b|KiB\b|kB\b"
    r"|bytes\b|instructions\b|points/s\b|evaluations\b))")

# A mantissa of one digit other than 1 times a power of ten, in either notation.
POWERS = re.compile(r"(?<![\w.\-])(?:[2-9]e[-+]?\d+|\d(?:\.\d+)?\s?×\s?10[⁻⁰¹²³⁴⁵⁶⁷⁸⁹]+)")
# A number of times: not a matrix's or a grid's size (2 × 2), nor a bound in units of a
# setting (10 × the tolerance, 2 × the budget, 6 × h).
TIMES = re.compile(r"(?<![\w.\-])\d+(?:\.\d+)?\s?×(?!\s?\d)"
                   r"(?!\s?(?:the\s+)?(?:tolerance|tol|budget|h)\b)")
# A multiple in words, as a comparison (twice as fast, ten times longer).
WORDS = re.compile(r"\b(?:twice|thrice|(?:two|three|four|five|six|seven|eight|nine|ten|"
                   r"eleven|twelve|twenty|thirty|forty|fifty|a hundred|a thousand)\s+times)"
                   r"(?=\s+(?:as|more|less|fewer|faster|slower|longer|shorter|larger|smaller|"
                   r"higher|lower|cheaper|dearer)\b)", re.IGNORECASE)

# Numbers with the look of a measurement that are not one, with the reason.
NOT_MEASURED = {
    "95 %": "the intervals' confidence level",
    "1.5e-6": "the step-size control's loosest internal tolerance, a constant of the code",
    "≥ 1.3×": "a target",
    "≥ 1.8×": "a target",
    "1280 × 800": "a window's size",
    "in 13 ms": "a test's input ramp",
    "h = 4e-4, 2e-4, 1e-4": "the forward Euler steps of a test",
    "at most 2e-12 relative": "the projection's bound, a constant of the code",
    "down to 5e-324 s": "the smallest positive double",
    "| all 8 decimals equal | 2e-8 |": "the bound a test holds the published decimals to",
    "of 1e-4 and 2e-4 of the value": "the difference steps of a test",
}


def significant(number):
    digits = re.sub(r"e.*", "", number.lower())
    return len(re.sub(r"\D", "", digits).strip("0"))


def measured_figures(prose):
    """The figures of `prose` with the look of a measurement: a number with two or more
    significant digits and a unit of time, size, share or ratio; a mantissa with decimals,
    or of one digit other than 1, times a power of ten (``5.1e-10``, ``4e-16``,
    ``2.5 × 10⁵``); any number of times (``100×``) but a bound (``≥ 5×``); a multiple in
    words (``twice``, ``ten times``). Settings and targets are round (1e-8, 10 s, 50 %,
    10⁵) and pass."""
    found = [m.group(0) for m in MEASURED.finditer(prose) if significant(m.group(0)) >= 2]
    found += [m.group(0) for m in POWERS.finditer(prose)]
    found += [m.group(0) for m in TIMES.finditer(prose)
              if not re.search(r"(≥|≤|>|<|at least|at most)\s*$", prose[:m.start()])
              and significant(m.group(0)) < 2]
    found += [m.group(0) for m in WORDS.finditer(prose)]
    return found


def test_no_measured_figure_is_stated_without_its_report():
    """A number with the look of a measurement (`measured_figures`) in README.md or
    docs/*.md must be a quote of a report row (above) or be named in NOT_MEASURED with why.
    Code blocks and inline code are commands and code, not statements of a measurement."""
    unlinked = []
    for doc in documents():
        fenced = False
        for i, line in enumerate(doc.read_text().splitlines(), 1):
            if line.lstrip().startswith("```"):
                fenced = not fenced
                continue
            if fenced:
                continue
            prose = QUOTE.sub(lambda m: " " if (doc.parent / m.group(2)).resolve().parent == REPORTS else m.group(0), line)
            prose = re.sub(r"`[^`]*`|\]\([^)]*\)", " ", prose)
            for phrase in NOT_MEASURED:
                prose = prose.replace(phrase, " ")
            unlinked += [f"{doc.relative_to(ROOT)}:{i}: {f}" for f in measured_figures(prose)]
    assert not unlinked, (f"{len(unlinked)} measured-looking figures quote no report row:\n"
                          + "\n".join(unlinked))


def test_the_figure_checks_catch_a_wrong_figure():
    """The checks above can fail: a figure off in its last printed digit, a label naming
    two rows, and an unlinked measurement of every look are each caught."""
    assert agrees("5.1e-10", "5.08e-10") and agrees("47", "47.3") and agrees("82.5", "82.5")
    assert not agrees("5.2e-10", "5.08e-10") and not agrees("48", "47.3")
    assert not agrees("5.08e-10", "5.1e-10")  # more digits than the report prints
    assert values("2 159 545 calls, 1,096 and −1.5e-3") == ["2159545", "1096", "-1.5e-3"]
    assert [m.group(0) for m in MEASURED.finditer("took 27.3 ns, 47×, 1e-8 and 10 s; 5.1e-10")] == [
        "27.3 ns", "47×", "10 s", "5.1e-10"]
    assert measured_figures("stays ≤ 4e-16 m, 100× faster, 2.5 × 10⁵ runs, twice as fast, "
                            "ten times longer") == [
        "4e-16", "2.5 × 10⁵", "100×", "twice", "ten times"]
    assert measured_figures("tol 1e-8, 10⁵ points, at least 5× faster, ≥ 2× the speed, a 2×2 "
                            "block, a 20 × 20 grid, 10 × tol, named twice") == []


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


def _field_check(root):
    return subprocess.run([sys.executable, "-m", "fmusweep.schema.docs", "--check",
                           "--root", str(root)], capture_output=True, text=True)


def test_the_docs_field_tables_are_the_declared_schema():
    checked = _field_check(ROOT)
    assert checked.returncode == 0, checked.stderr


def test_a_field_without_its_line_in_the_docs_fails_the_check(tmp_path):
    for page in ("docs/sweeps.md", "docs/fitting.md", "docs/cycle.md"):
        (tmp_path / page).parent.mkdir(exist_ok=True)
        (tmp_path / page).write_text((ROOT / page).read_text())
    page = tmp_path / "docs/sweeps.md"
    lines = page.read_text().splitlines(keepends=True)
    tolerance = next(i for i, line in enumerate(lines) if line.startswith("| tolerance |"))
    page.write_text("".join(lines[:tolerance] + lines[tolerance + 1:]))
    checked = _field_check(tmp_path)
    assert checked.returncode == 1
    assert "docs/sweeps.md: its field tables differ" in checked.stderr


def test_every_declared_field_has_a_meaning():
    from fmusweep.schema.core import Table, field
    from fmusweep.schema.docs import table_rows

    class Unexplained(Table):
        said: float = field("what it is", 1.0)
        unsaid: float = 2.0

    with pytest.raises(ValueError, match="Unexplained.unsaid has no meaning"):
        list(table_rows(Unexplained))
