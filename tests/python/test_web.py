"""The live page (`cargo xtask web`), opened from its file URL in headless Chromium as a
user opens it: the linkage moves, a slider changes the run (at once for a spring, from a
new start for a length), a geometry that cannot close and a change point are shown as
such while the page goes on responding, pause stops the clock, and the console stays
clean."""

import io
import time

import numpy as np
import pytest
from PIL import Image

from browser import Browser, chromium
from conftest import packed

pytestmark = pytest.mark.skipif(chromium() is None, reason="Debian's chromium is not installed "
                                "(cargo xtask test installs it)")

SNAPSHOT = "window.mechanismPage.snapshot()"
# What a user does: drag a slider (input events) or type into the number beside it.
DRAG = """(function(name, value){
  const s = document.getElementById('slider-' + name); s.value = value;
  s.dispatchEvent(new Event('input')); return Number(s.value);
})"""
TYPE = """(function(name, value){
  const f = document.getElementById('value-' + name); f.value = value;
  f.dispatchEvent(new Event('change'));
})"""


@pytest.fixture(scope="module")
def page():
    return packed("MECHANISM_WEB_PAGE", "target/web/index.html", "web")


@pytest.fixture
def browser(page):
    with Browser(width=1500, height=1000) as b:
        b.open(page)
        b.wait_for("window.mechanismPage !== undefined && window.mechanismPage.snapshot().t > 0.2")
        yield b
        assert b.errors == [], b.errors


def canvas_pixels(b):
    """A screenshot of the linkage's canvas, as an array of pixels."""
    box = b.evaluate("(() => { const r = document.getElementById('linkage').getBoundingClientRect();"
                     " return [r.left, r.top, r.width, r.height]; })()")
    clip = dict(zip(("x", "y", "width", "height"), box), scale=1)
    data = b.call("Page.captureScreenshot", format="png", clip=clip)["data"]
    import base64
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(data))).convert("RGB"), dtype=int)


def time_moves_on(b, beyond, timeout=10):
    return b.wait_for(f"{SNAPSHOT}.t > {beyond} && {SNAPSHOT}", timeout)


# The page's clock and its simulated time, read together.
CLOCK = f"(function(){{ const s = {SNAPSHOT}; s.wall = performance.now() / 1000; return s; }})()"


def test_the_linkage_moves_in_real_time(browser):
    first = canvas_pixels(browser)
    before = browser.evaluate(CLOCK)
    time.sleep(1.0)
    second = canvas_pixels(browser)
    after = browser.evaluate(CLOCK)
    # Simulated time follows the page's wall clock: never ahead of it by more than the one
    # frame the page may step ahead (0.1 s), and, on a page this cheap, not far behind it.
    simulated, wall = after["t"] - before["t"], after["wall"] - before["wall"]
    assert simulated <= wall + 0.1 + 1 / 200, (simulated, wall)
    assert simulated >= 0.5 * wall, (simulated, wall)
    changed = np.any(first != second, axis=2)
    assert changed.sum() > 200, "the linkage was drawn in the same place twice"
    # The pixels that changed lie where the linkage is: around the crank and the rocker,
    # not in the title or at the edges.
    rows, columns = np.nonzero(changed)
    assert 0.05 < columns.mean() / changed.shape[1] < 0.95
    assert after["t"] > before["t"] and after["values"]["phi2"] != before["values"]["phi2"]
    assert after["ok"] and after["problem"] is None
    assert abs(after["values"]["constraint_residual"]) < 1e-9


def test_a_spring_slider_acts_at_once_and_a_length_starts_over(browser):
    mech = "window.mechanismPage.mech"
    assert browser.evaluate(f"{mech}.get('k34')") == 100.0
    going = browser.evaluate(SNAPSHOT)["t"]
    set_to = browser.evaluate(f"{DRAG}('k34', 300)")
    assert browser.evaluate(f"{mech}.get('k34')") == set_to == 300.0
    assert browser.evaluate(SNAPSHOT)["t"] >= going, "a spring's change restarted the run"
    time_moves_on(browser, going + 0.3)
    # The rod's length: a new start with it (and with k34 kept).
    browser.evaluate(f"{TYPE}('L', 0.75)")
    after = browser.evaluate(SNAPSHOT)
    assert after["t"] < going and after["ok"]
    assert browser.evaluate(f"{mech}.get('L')") == 0.75
    assert browser.evaluate(f"{mech}.get('k34')") == 300.0
    time_moves_on(browser, after["t"] + 0.3)


def test_a_geometry_that_cannot_close_is_shown_and_the_page_goes_on(browser, tmp_path):
    browser.evaluate(f"{TYPE}('L', 2.0)")
    state = browser.evaluate(SNAPSHOT)
    assert not state["ok"] and state["problem"].startswith("no start:"), state
    assert "L = 2" in state["problem"]
    shown = browser.evaluate("document.getElementById('problem').hidden")
    assert shown is False
    # Frames keep coming, and the sliders keep working.
    time.sleep(1.2)
    assert browser.evaluate(SNAPSHOT)["framesPerSecond"] > 5
    browser.screenshot(tmp_path / "no-closure.png")
    browser.evaluate(f"{TYPE}('L', 0.7)")
    assert browser.evaluate(SNAPSHOT)["ok"]
    time_moves_on(browser, 0.3)
    assert browser.evaluate("document.getElementById('problem').hidden") is True


def test_a_change_point_is_crossed_and_shown(browser):
    # A parallelogram turning freely: crank, rod and rocker line up twice a turn.
    for name, value in [("l", 0.5), ("l2", 0.5), ("l3", 0.5), ("L", 0.5), ("phi2_0", 1.0),
                        ("omega2_0", 3.0)]:
        browser.evaluate(f"{TYPE}('{name}', {value})")
    browser.evaluate("document.getElementById('laws').click()")
    state = browser.wait_for(f"{SNAPSHOT}.crossings > 0 && {SNAPSHOT}", timeout=15)
    assert state["ok"] and state["problem"] is None
    note = browser.evaluate("document.getElementById('event').textContent")
    assert "a change point" in note and "so far" in note, note
    assert browser.evaluate("window.mechanismPage.history.marks.length") > 0
    time_moves_on(browser, state["t"] + 0.5)


def test_pause_stops_the_clock_and_start_goes_on(browser):
    browser.evaluate("document.getElementById('run').click()")
    paused = browser.evaluate(SNAPSHOT)["t"]
    time.sleep(0.4)
    assert browser.evaluate(SNAPSHOT)["t"] == paused
    assert browser.evaluate("document.getElementById('run').textContent") == "Start"
    browser.evaluate("document.getElementById('run').click()")
    time_moves_on(browser, paused + 0.2)
    browser.evaluate("document.getElementById('reset').click()")
    assert browser.evaluate(SNAPSHOT)["t"] < paused + 0.2


def test_the_page_is_self_contained(page):
    html = page.read_text()
    assert "http" not in html
    for name in ("page.js", "mechanism.js", "style.css"):
        text = (page.parent / name).read_text()
        assert "fetch(" not in text and "http://" not in text and "https://" not in text


def test_every_parameter_input_and_the_branch_has_a_control_from_the_module(browser):
    offered = browser.evaluate("""window.mechanismPage.mech.variables
        .filter((v) => ['parameter', 'input'].includes(v.causality) && v.group).map((v) => v.name)""")
    for name in ("Mm_a2", "Mr_b1", "change_point_branch", "twist12_0", "M_r", "k34", "L"):
        assert name in offered, name
    # Every variable the module gives a group has its control, and no other has one.
    ids = browser.evaluate("[...document.querySelectorAll('#controls input, #controls select')]"
                           ".map((e) => e.id)")
    controlled = {i.split("-", 1)[1] for i in ids}
    assert controlled == set(offered)
    legends = browser.evaluate("[...document.querySelectorAll('#controls legend')]"
                               ".map((e) => e.textContent)")
    assert "Built-in laws" in legends and "Change points" in legends
    # The quadratic motor coefficient acts at once, as a law's coefficient does.
    going = browser.evaluate(SNAPSHOT)["t"]
    browser.evaluate(f"{TYPE}('Mm_a2', -2.5)")
    assert browser.evaluate("window.mechanismPage.mech.get('Mm_a2')") == -2.5
    assert browser.evaluate(SNAPSHOT)["t"] >= going
    # The branch is chosen by its items' names.
    options = browser.evaluate("[...document.getElementById('choice-change_point_branch').options]"
                               ".map((o) => [o.value, o.text, o.selected])")
    assert len(options) >= 2 and all(text and not text.isdigit() for _, text, _ in options)
    other = next(value for value, _, selected in options if not selected)
    browser.evaluate(f"""(() => {{ const s = document.getElementById('choice-change_point_branch');
        s.value = '{other}'; s.dispatchEvent(new Event('change')); }})()""")
    assert browser.evaluate("window.mechanismPage.mech.get('change_point_branch')") == int(other)
    assert browser.evaluate(SNAPSHOT)["ok"]


# Every control's box on the page, with its id: the module's controls and the buttons.
CONTROL_BOXES = ("[...document.querySelectorAll('#controls input, #controls select, "
                 "#buttons button, #buttons input')].map((e) => { const r = "
                 "e.getBoundingClientRect(); return [e.id, r.left, r.top, r.right, r.bottom]; })")


def test_a_laptop_window_shows_every_control_at_once(page, tmp_path):
    """At 1280 × 800 every control lies inside the window: none below the fold, none to
    the side, the page scrolls neither way (as docs/web.md says)."""
    with Browser(width=1280, height=800) as b:
        b.open(page)
        b.wait_for("window.mechanismPage !== undefined && window.mechanismPage.snapshot().t > 0.1")
        assert b.evaluate("document.documentElement.scrollWidth") <= 1280
        boxes = b.evaluate(CONTROL_BOXES)
        assert len(boxes) > 30, boxes
        outside = [box for box in boxes if box[1] < 0 or box[2] < 0 or box[3] > 1280
                   or box[4] > 800]
        assert outside == [], outside
        b.screenshot(tmp_path / "laptop.png")
        assert b.errors == [], b.errors
