"""The live page's benchmark: paper case 1 (10 s, H = 0.01, tol 1e-10, every output read at
every point) stepped by the WebAssembly module inside headless Chromium, beside the native
library and the module under Node timed by `cargo xtask bench-web` in the same run; the
page's frames per second and simulated seconds per wall second while it runs live; the
size of the page; a screenshot.

    python bench/bench_web.py <index.html> <output directory> --native-seconds S
        --node-seconds S [--quick]

Writes results.json, results.md and page.png.
"""

import json
import pathlib
import statistics
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests/python"))
sys.path.insert(0, str(ROOT / "bench"))
from bench_sweep import machine, write_results  # noqa: E402
from browser import Browser  # noqa: E402

# Paper case 1 as the C master runs it: the same grid k·H, the same 16 outputs read at
# every point; the fastest of `repeats` runs, each on a fresh module.
FLAT_OUT = """(async function(repeats, outputs){
  let fastest = Infinity, last = null;
  for (let r = 0; r < repeats; r++) {
    const mech = await Mechanism.load(), m = mech.m;
    const vrs = outputs.map((n) => mech.byName.get(n).vr);
    if (m.mechanism_start(1e-10, 0.0, 10.0) !== 0) throw new Error(mech.message());
    const values = new Float64Array(1001 * vrs.length);
    let t = 0.0;
    const started = performance.now();
    for (let k = 1; k <= 1000; k++) {
      const next = k * 0.01;
      if (m.mechanism_step(t, next - t) === 1) throw new Error(mech.message());
      t = next;
      for (let i = 0; i < vrs.length; i++) values[k * vrs.length + i] = m.mechanism_get(vrs[i]);
    }
    fastest = Math.min(fastest, (performance.now() - started) / 1000);
    last = values[1000 * vrs.length + 1];
  }
  return [fastest, last];
})"""
OUTPUTS = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4", "rod_force",
           "constraint_residual", "energy", "n_steps", "n_rejected", "n_rhs", "active_solver",
           "linkage_class"]


def option(name: str) -> float:
    return float(sys.argv[sys.argv.index(name) + 1])


def main():
    page, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    quick = "--quick" in sys.argv
    out.mkdir(parents=True, exist_ok=True)
    r = {"machine": machine(), "quick": quick,
         "native_s": option("--native-seconds"), "node_s": option("--node-seconds")}
    files = sorted(p for p in page.parent.iterdir() if p.is_file())
    r["page_files"] = {p.name: p.stat().st_size for p in files}
    r["page_bytes"] = sum(r["page_files"].values())
    with Browser(width=1500, height=1000) as b:
        b.open(page)
        b.wait_for("window.mechanismPage !== undefined")
        seconds, phi2 = b.evaluate(f"{FLAT_OUT}({2 if quick else 7}, {json.dumps(OUTPUTS)})")
        r["chromium_s"], r["chromium_phi2_at_10s"] = seconds, phi2
        # The live run: a fresh start, then a second's frames and pace, sampled.
        b.evaluate("document.getElementById('reset').click()")
        time.sleep(2)
        samples = []
        for _ in range(3 if quick else 8):
            time.sleep(1)
            samples.append(b.evaluate("window.mechanismPage.snapshot()"))
        r["frames_per_second"] = statistics.median(s["framesPerSecond"] for s in samples)
        r["real_time_factor"] = statistics.median(s["realTimeFactor"] for s in samples)
        r["live_ok"] = all(s["ok"] for s in samples)
        b.screenshot(out / "page.png")
        r["errors"] = b.errors
    write_results(out, r, report(r))


def report(r) -> str:
    ratio = r["chromium_s"] / r["native_s"]
    lines = [
        "# Live page benchmark", "",
        f"Machine: {r['machine']}. Paper case 1 (10 s of motion, H = 0.01, tol 1e-10, the 16 "
        "outputs read at every communication point), the fastest of several runs of each, all "
        "in one run of `cargo xtask bench-web`. Headless Chromium (Debian's package, no GPU).", "",
        "| stepped by | time per 10 s of motion | against the native library |",
        "| --- | --- | --- |",
        f"| the native library (linux64, the C master) | {r['native_s'] * 1e3:.2f} ms | 1 |",
        f"| the wasm32 module under Node | {r['node_s'] * 1e3:.2f} ms | "
        f"{r['node_s'] / r['native_s']:.2f}× |",
        f"| the wasm32 module in Chromium | {r['chromium_s'] * 1e3:.2f} ms | {ratio:.2f}× |",
        "",
        "Each Node run is a fresh process that compiles the module and runs the loop once, "
        "mostly on V8's baseline code; in Chromium the fastest of the runs in one page is "
        "taken, on optimised code. The native library steps with its AVX copy where the "
        "processor has AVX, the module with 128-bit SIMD.", "",
        f"The live page (tol 1e-6, H = 1/200 s, drawing every frame): "
        f"{r['frames_per_second']:.0f} frames per second, {r['real_time_factor']:.2f} simulated "
        f"seconds per wall second (the median of {8 if not r['quick'] else 3} one-second "
        f"samples){'' if r['live_ok'] else ', with a failed run'}.", "",
        f"The page: {r['page_bytes'] / 1e6:.3f} MB in {len(r['page_files'])} files "
        f"({', '.join(f'{k} {v / 1e3:.1f} kB' for k, v in r['page_files'].items())}).", "",
        f"Console errors: {len(r['errors'])}.", "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
