"use strict";
// The live page: the mechanism's module (mechanism.js, the crate web/ built for wasm32)
// steps in real time; each frame draws the linkage and the curves. The variables, their
// units, ranges, which of them act on a running mechanism and the controls the page
// offers (their groups and slider spans) come from the module itself.

// Communication step of the page (s): every curve sample and every drawn state is a point
// of this grid, k·H, as a master's.
const H = 1 / 200;
const TOLERANCE = 1e-6;
// Seconds of motion the curves keep.
const WINDOW = 10;
// Wall time simulated at most per frame (after the tab was hidden, say), and the share of a
// 60 Hz frame the stepping may take before the run falls behind real time.
const MAX_FRAME = 0.1;
const STEP_BUDGET_MS = 12;

const RECORDED = ["phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
  "energy", "constraint_residual", "rod_force"];

class Mechanism {
  constructor(instance) {
    this.m = instance.exports;
    this.m.mechanism_describe();
    this.variables = JSON.parse(this.message());
    this.byName = new Map(this.variables.map((v) => [v.name, v]));
  }

  static async load() {
    const bytes = Uint8Array.from(atob(MECHANISM_WASM), (c) => c.charCodeAt(0));
    const { instance } = await WebAssembly.instantiate(bytes, {});
    return new Mechanism(instance);
  }

  message() {
    const m = this.m;
    const bytes = new Uint8Array(m.memory.buffer, m.mechanism_message(), m.mechanism_message_length());
    return new TextDecoder().decode(bytes);
  }

  // null, or why the module refused.
  set(name, value) {
    return this.m.mechanism_set(this.byName.get(name).vr, value) === 0 ? null : this.message();
  }

  get(name) {
    return this.m.mechanism_get(this.byName.get(name).vr);
  }

  reset() { this.m.mechanism_reset(); }

  start() {
    return this.m.mechanism_start(TOLERANCE, 0.0, Infinity) === 0 ? null : this.message();
  }

  // 0 plain, 2 over a change point; a refusal's reason as a string.
  step(t, h) {
    const status = this.m.mechanism_step(t, h);
    return status === 1 ? this.message() : status;
  }

  itemName(name, value) {
    const items = this.byName.get(name).items || {};
    return items[String(value)] || String(value);
  }
}

// Samples of the last WINDOW seconds, in columns.
class History {
  constructor(names) {
    this.names = names;
    this.clear();
  }

  clear() {
    this.t = [];
    this.columns = Object.fromEntries(this.names.map((n) => [n, []]));
    this.marks = [];
  }

  push(t, values) {
    this.t.push(t);
    for (const n of this.names) this.columns[n].push(values[n]);
    const keep = Math.round(WINDOW / H) + 1;
    if (this.t.length > 2 * keep) {
      this.t = this.t.slice(-keep);
      for (const n of this.names) this.columns[n] = this.columns[n].slice(-keep);
      this.marks = this.marks.filter((m) => m >= this.t[0]);
    }
  }
}

// A line chart of some columns of a History over the last WINDOW seconds.
class Chart {
  constructor(canvas, title, series) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.title = title;
    this.series = series;
  }

  draw(history) {
    const { ctx, canvas } = this;
    const [w, h] = [canvas.width, canvas.height];
    const pad = { l: 62, r: 10, t: 20, b: 18 };
    ctx.clearRect(0, 0, w, h);
    ctx.font = "12px system-ui, sans-serif";
    ctx.fillStyle = "#1d2330";
    ctx.fillText(this.title, pad.l, 13);
    const t = history.t;
    if (t.length < 2) return;
    const t1 = t[t.length - 1], t0 = Math.max(t[0], t1 - WINDOW);
    const first = t.findIndex((x) => x >= t0);
    let lo = Infinity, hi = -Infinity;
    for (const s of this.series) {
      const col = history.columns[s.name];
      for (let i = first; i < col.length; i++) {
        const y = s.map ? s.map(col[i]) : col[i];
        if (y < lo) lo = y;
        if (y > hi) hi = y;
      }
    }
    if (!(hi > lo)) { hi = lo + 1e-12 + Math.abs(lo) * 1e-6; lo -= 1e-12 + Math.abs(lo) * 1e-6; }
    const X = (x) => pad.l + (x - t0) / Math.max(t1 - t0, H) * (w - pad.l - pad.r);
    const Y = (y) => h - pad.b - (y - lo) / (hi - lo) * (h - pad.t - pad.b);
    ctx.strokeStyle = "#d6dae1";
    ctx.strokeRect(pad.l, pad.t, w - pad.l - pad.r, h - pad.t - pad.b);
    ctx.fillStyle = "#4a5160";
    ctx.textAlign = "right";
    ctx.fillText(format(hi), pad.l - 4, pad.t + 9);
    ctx.fillText(format(lo), pad.l - 4, h - pad.b);
    ctx.textAlign = "left";
    ctx.fillText(`t = ${t0.toFixed(1)} … ${t1.toFixed(1)} s`, pad.l, h - 4);
    ctx.strokeStyle = "#c08a00";
    for (const m of history.marks) {
      if (m < t0) continue;
      ctx.beginPath(); ctx.moveTo(X(m), pad.t); ctx.lineTo(X(m), h - pad.b); ctx.stroke();
    }
    let x = w - pad.r;
    for (const s of [...this.series].reverse()) {
      const col = history.columns[s.name];
      ctx.strokeStyle = s.color;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      // At most two points per pixel column.
      const stride = Math.max(1, Math.floor((col.length - first) / (2 * (w - pad.l - pad.r))));
      let previous = null;
      for (let i = first; i < col.length; i += stride) {
        const y = s.map ? s.map(col[i]) : col[i];
        // A wrapped angle's jump is not drawn as a line.
        const jump = s.map && previous !== null && Math.abs(y - previous) > Math.PI;
        if (previous === null || jump) ctx.moveTo(X(t[i]), Y(y)); else ctx.lineTo(X(t[i]), Y(y));
        previous = y;
      }
      ctx.stroke();
      ctx.lineWidth = 1;
      ctx.fillStyle = s.color;
      ctx.textAlign = "right";
      ctx.fillText(s.label || s.name, x, 13);
      x -= ctx.measureText(s.label || s.name).width + 12;
      ctx.textAlign = "left";
    }
  }
}

function format(x) {
  if (x === 0) return "0";
  const a = Math.abs(x);
  return a >= 1e4 || a < 1e-3 ? x.toExponential(2) : x.toPrecision(4);
}

function label(text, target) {
  const element = document.createElement("label");
  element.htmlFor = target;
  element.textContent = text;
  return element;
}

function input(attributes) {
  const element = document.createElement("input");
  for (const [name, value] of Object.entries(attributes)) element.setAttribute(name, value);
  return element;
}

const TWO_PI = 2 * Math.PI;
const wrap = (a) => ((a % TWO_PI) + TWO_PI) % TWO_PI;

// The page's state and its loop.
class Page {
  constructor(mechanism) {
    this.mech = mechanism;
    this.settings = new Map(); // what the user changed, by name
    this.history = new History(RECORDED);
    this.running = true;
    this.frames = [];
    this.rates = [];
    this.charts = [
      new Chart(document.getElementById("chart-angles"), "angles (rad)", [
        { name: "phi2", label: "φ2 mod 2π", color: "#1f5fbf", map: wrap },
        { name: "phi3", label: "φ3", color: "#c0392b" }]),
      new Chart(document.getElementById("chart-speeds"), "speeds (rad/s)", [
        { name: "omega1", label: "ω1", color: "#7f8c8d" }, { name: "omega2", label: "ω2", color: "#1f5fbf" },
        { name: "omega3", label: "ω3", color: "#c0392b" }, { name: "omega4", label: "ω4", color: "#27ae60" }]),
      new Chart(document.getElementById("chart-energy"), "energy (J)", [
        { name: "energy", label: "energy", color: "#8e44ad" }]),
      new Chart(document.getElementById("chart-residual"), "constraint residual |A2A3| − L (m)", [
        { name: "constraint_residual", label: "residual", color: "#d35400" }]),
    ];
    this.canvas = document.getElementById("linkage");
    this.buildControls();
    document.getElementById("run").addEventListener("click", () => this.toggle());
    document.getElementById("reset").addEventListener("click", () => this.restart());
    const laws = document.getElementById("laws");
    laws.addEventListener("change", () => this.change("builtin_laws", laws.checked ? 1 : 0));
    this.restart();
    requestAnimationFrame((now) => this.frame(now));
  }

  // A control for each variable the module offers one (its group, and for a number the
  // span of its slider): a slider and a number field, or a choice among an Enumeration's
  // items.
  buildControls() {
    const panel = document.getElementById("controls");
    const groups = new Map();
    for (const v of this.mech.variables.filter((v) => v.group)) {
      if (!groups.has(v.group)) {
        const set = document.createElement("fieldset");
        set.innerHTML = `<legend>${v.group}</legend>`;
        panel.appendChild(set);
        groups.set(v.group, set);
      }
      const row = document.createElement("div");
      row.className = "control";
      row.title = `${v.description}${v.live ? "" : " (starts the run over)"}`;
      row.appendChild(label(v.name, v.items ? `choice-${v.name}` : `slider-${v.name}`));
      if (v.items) row.appendChild(this.choice(v)); else row.append(...this.slider(v));
      groups.get(v.group).appendChild(row);
    }
  }

  slider(v) {
    const [low, high] = v.span;
    const [min, max] = [Math.max(low, v.min ?? low), Math.min(high, v.max ?? high)];
    const start = v.start ?? 0;
    const slider = input({ type: "range", id: `slider-${v.name}`, min, max, step: (max - min) / 500, value: start });
    const field = input({ type: "number", id: `value-${v.name}`, step: "any", value: start });
    field.setAttribute("aria-label", `${v.name} (${v.unit})`);
    slider.addEventListener("input", () => { field.value = slider.value; this.change(v.name, Number(slider.value)); });
    field.addEventListener("change", () => { slider.value = field.value; this.change(v.name, Number(field.value)); });
    return [slider, field];
  }

  choice(v) {
    const select = document.createElement("select");
    select.id = `choice-${v.name}`;
    for (const [value, name] of Object.entries(v.items)) {
      const option = new Option(name, value, false, Number(value) === v.start);
      select.appendChild(option);
    }
    select.addEventListener("change", () => this.change(v.name, Number(select.value)));
    return select;
  }

  // A user's change: at once where the module takes it on a running mechanism, otherwise
  // from a new start.
  change(name, value) {
    this.settings.set(name, value);
    if (this.ok && this.mech.byName.get(name).live) {
      const refused = this.mech.set(name, value);
      this.showProblem(refused && `${name}: ${refused}`);
      return;
    }
    this.restart();
  }

  restart() {
    const m = this.mech;
    m.reset();
    this.k = 0;
    this.simulated = 0; // wall seconds of running since the start
    this.history.clear();
    this.lastEvent = null;
    document.getElementById("event").hidden = true;
    for (const [name, value] of this.settings) {
      const refused = m.set(name, value);
      if (refused) { this.fail(`${name}: ${refused}`); return; }
    }
    const refused = m.start();
    if (refused) { this.fail(refused); return; }
    this.ok = true;
    this.showProblem(null);
    this.geometry = ["l", "l2", "l3", "L"].map((n) => m.get(n));
    this.record();
  }

  fail(reason) {
    this.ok = false;
    this.showProblem(reason);
  }

  showProblem(reason) {
    const p = document.getElementById("problem");
    p.hidden = !reason;
    p.textContent = reason || "";
  }

  toggle() {
    this.running = !this.running;
    document.getElementById("run").textContent = this.running ? "Pause" : "Start";
  }

  record() {
    const values = {};
    for (const n of RECORDED) values[n] = this.mech.get(n);
    this.values = values;
    this.history.push(this.k * H, values);
  }

  // Step on to the wall clock, within the frame's budget.
  advance(wall) {
    this.simulated += Math.min(wall, MAX_FRAME);
    const started = performance.now();
    while ((this.k + 1) * H <= this.simulated && performance.now() - started < STEP_BUDGET_MS) {
      const t = this.k * H;
      const outcome = this.mech.step(t, (this.k + 1) * H - t);
      if (typeof outcome === "string") { this.fail(outcome); return; }
      this.k += 1;
      this.record();
      if (outcome === 2) this.changePoint();
    }
    // Behind by more than a frame: real time is out of reach, the run goes on at its pace.
    this.simulated = Math.min(this.simulated, (this.k + 1) * H + MAX_FRAME);
  }

  changePoint() {
    const at = this.mech.m.mechanism_last_crossing();
    this.history.marks.push(at);
    const note = document.getElementById("event");
    note.hidden = false;
    note.textContent = `t = ${at.toFixed(3)} s: a change point (crank, rod and rocker in line), ` +
      `crossed onto the branch "${this.mech.itemName("change_point_branch", this.mech.get("change_point_branch"))}"; ` +
      `${this.mech.m.mechanism_crossings()} so far`;
  }

  frame(now) {
    if (this.last !== undefined) {
      const wall = (now - this.last) / 1000;
      if (this.running && this.ok) {
        const before = this.k;
        this.advance(wall);
        this.rates.push([now, (this.k - before) * H]);
      }
      this.frames.push(now);
    }
    this.last = now;
    while (this.frames.length && this.frames[0] < now - 1000) this.frames.shift();
    while (this.rates.length && this.rates[0][0] < now - 1000) this.rates.shift();
    this.drawLinkage();
    for (const chart of this.charts) chart.draw(this.history);
    this.drawNumbers();
    requestAnimationFrame((next) => this.frame(next));
  }

  // What the page measures and shows, also read by the tests and the benchmark.
  snapshot() {
    const span = this.rates.length > 1 ? (this.rates[this.rates.length - 1][0] - this.rates[0][0]) / 1000 : 0;
    const simulated = this.rates.slice(1).reduce((sum, [, s]) => sum + s, 0);
    return {
      t: this.k * H, ok: this.ok, running: this.running,
      problem: document.getElementById("problem").hidden ? null : document.getElementById("problem").textContent,
      crossings: this.mech.m.mechanism_crossings(),
      framesPerSecond: this.frames.length,
      realTimeFactor: span > 0 ? simulated / span : 0,
      values: this.values,
    };
  }

  drawNumbers() {
    const m = this.mech, s = this.snapshot();
    const rows = [["t", `${s.t.toFixed(2)} s`],
      ["simulated / wall", `${s.realTimeFactor.toFixed(2)} (${s.framesPerSecond} frames/s)`]];
    if (this.ok) {
      rows.push(["steps", `${m.get("n_steps")} (${m.get("n_rejected")} rejected)`],
        ["right-hand sides", String(m.get("n_rhs"))],
        ["method", m.itemName("active_solver", m.get("active_solver"))],
        ["linkage", m.itemName("linkage_class", m.get("linkage_class"))],
        ["change points", String(s.crossings)],
        ["energy", `${format(this.values.energy)} J`],
        ["rod force", `${format(this.values.rod_force)} N`],
        ["residual", `${format(this.values.constraint_residual)} m`]);
    }
    document.querySelector("#numbers tbody").innerHTML =
      rows.map(([a, b]) => `<tr><td>${a}</td><td>${b}</td></tr>`).join("");
  }

  drawLinkage() {
    const ctx = this.canvas.getContext("2d");
    const [w, h] = [this.canvas.width, this.canvas.height];
    ctx.clearRect(0, 0, w, h);
    if (!this.ok) {
      ctx.fillStyle = "#a03030";
      ctx.font = "15px system-ui, sans-serif";
      ctx.textAlign = "center";
      ctx.fillText("no motion: see the message below", w / 2, h / 2);
      ctx.textAlign = "left";
      return;
    }
    const [l, l2, l3] = this.geometry;
    const { phi1, phi2, phi3, phi4 } = this.values;
    const reach = Math.max(l2, l3);
    const [x0, x1, y0, y1] = [-reach, l + reach, -reach, reach];
    const scale = 0.9 * Math.min(w / (x1 - x0), h / (y1 - y0));
    const P = ([x, y]) => [w / 2 + (x - (x0 + x1) / 2) * scale, h / 2 - (y - (y0 + y1) / 2) * scale];
    const O2 = [0, 0], O3 = [l, 0];
    const A2 = [l2 * Math.cos(phi2), l2 * Math.sin(phi2)];
    const A3 = [l + l3 * Math.cos(phi3), l3 * Math.sin(phi3)];
    const disc = (c, r, angle, color) => {
      const [cx, cy] = P(c);
      ctx.fillStyle = color;
      ctx.beginPath(); ctx.arc(cx, cy, r, 0, TWO_PI); ctx.fill();
      ctx.strokeStyle = "#ffffff"; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + r * Math.cos(angle), cy - r * Math.sin(angle)); ctx.stroke();
    };
    const bar = (a, b, color, width) => {
      ctx.strokeStyle = color; ctx.lineWidth = width; ctx.lineCap = "round";
      ctx.beginPath(); ctx.moveTo(...P(a)); ctx.lineTo(...P(b)); ctx.stroke();
    };
    // Bodies 1 and 4 behind the crank and the rocker on their axes, a mark at their angles.
    const r = Math.max(12, 0.18 * reach * scale);
    disc(O2, r, phi1, "#b8c2cc");
    disc(O3, r, phi4, "#b8d8c0");
    ctx.strokeStyle = "#4a5160"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(...P([x0, -0.02 * reach])); ctx.lineTo(...P([x1, -0.02 * reach])); ctx.stroke();
    bar(O2, A2, "#1f5fbf", 8);
    bar(O3, A3, "#c0392b", 8);
    bar(A2, A3, "#2c3e50", 4);
    for (const p of [O2, O3, A2, A3]) {
      const [px, py] = P(p);
      ctx.fillStyle = "#ffffff"; ctx.strokeStyle = "#1d2330"; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.arc(px, py, 4, 0, TWO_PI); ctx.fill(); ctx.stroke();
    }
    ctx.fillStyle = "#1d2330";
    ctx.font = "12px system-ui, sans-serif";
    const placed = [];
    // The pivots' names below the ground line, the joints' beyond their links' ends; each
    // name where it meets no name placed before it.
    for (const [label, p, from] of [["O2", O2, null], ["O3", O3, null], ["A2", A2, O2], ["A3", A3, O3]]) {
      const box = labelBox(ctx, label, P(p), from && P(from), placed);
      placed.push(box);
      ctx.fillText(label, box.x, box.y + box.h);
    }
  }
}

/** Where a point's name goes: the first of its candidate places (beyond the link from
 * `from`, else below; then around the point) whose box meets none of `placed`. */
function labelBox(ctx, text, [px, py], from, placed) {
  const w = ctx.measureText(text).width, h = 10, gap = 9;
  const candidates = [];
  if (from) {
    const [dx, dy] = [px - from[0], py - from[1]];
    const n = Math.hypot(dx, dy) || 1;
    candidates.push([px + (dx / n) * (gap + w / 2) - w / 2, py + (dy / n) * (gap + h / 2) - h / 2]);
  } else {
    candidates.push([px - w / 2, py + gap]);
  }
  candidates.push([px + gap, py - gap - h], [px - gap - w, py - gap - h], [px + gap, py + gap],
                  [px - gap - w, py + gap], [px - w / 2, py - 2 * gap - h]);
  const meets = (a) => placed.some((b) => a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h);
  for (const [x, y] of candidates) {
    const box = { x, y, w, h };
    if (!meets(box)) return box;
  }
  return { x: candidates[0][0], y: candidates[0][1], w, h };
}

Mechanism.load().then((mechanism) => {
  window.mechanismPage = new Page(mechanism);
}).catch((error) => {
  document.getElementById("problem").hidden = false;
  document.getElementById("problem").textContent = `the module did not load: ${error}`;
  throw error;
});
