// A master for the WebAssembly module under Node, with the command line and the output of
// tests/platforms/master.c, so that its run is compared with linux64's FMU like the other
// platforms' (xtask/src/abi_tests.rs):
//
//   node node_master.mjs MODULE.wasm KEY TOLERANCE STEP STOP OUT [K:VR=VALUE ...] -- K:VR ...
//
// KEY (the FMU's guid or instantiation token) is not used: the module is not an FMU. Each
// line of OUT is a communication point: the time and every Real as the hex of its IEEE
// bits, an Integer in decimal. The stepping loop's time goes to stderr as loop_seconds.

import { readFileSync, writeFileSync } from "node:fs";
import { performance } from "node:perf_hooks";

function fail(what) {
    process.stderr.write(`node master: ${what}\n`);
    process.exit(1);
}

const args = process.argv.slice(2);
const separator = args.indexOf("--");
if (args.length < 6 || separator < 6) {
    fail("usage: MODULE KEY TOLERANCE STEP STOP OUT [K:VR=VALUE ...] -- K:VR ...");
}
const [file, , tolerance, step, stop, out] = args;
const settings = args.slice(6, separator);
const recorded = args.slice(separator + 1).map((spec) => {
    const [kind, vr] = spec.split(":");
    return { kind, vr: Number(vr) };
});

const { instance } = await WebAssembly.instantiate(readFileSync(file), {});
const m = instance.exports;

function message() {
    const bytes = new Uint8Array(m.memory.buffer, m.mechanism_message(), m.mechanism_message_length());
    return new TextDecoder().decode(bytes);
}

function check(status, call) {
    if (status === 1) fail(`${call}: ${message()}`);
}

for (const setting of settings) {
    const [target, value] = setting.split("=");
    const vr = Number(target.split(":")[1]);
    check(m.mechanism_set(vr, Number(value)), `set ${setting}`);
}
const h = Number(step);
const end = Number(stop);
check(m.mechanism_start(Number(tolerance), 0.0, end), "start");

const points = Math.floor(end / h + 0.5);
const values = new Float64Array((points + 1) * recorded.length);
function read(k) {
    recorded.forEach(({ vr }, i) => {
        values[k * recorded.length + i] = m.mechanism_get(vr);
        if (m.mechanism_get_status() !== 0) fail(`get ${vr}: ${message()}`);
    });
}

read(0);
let t = 0.0;
const started = performance.now();
for (let k = 1; k <= points; k++) {
    const next = k * h;
    check(m.mechanism_step(t, next - t), `step at t = ${t}`);
    t = next;
    read(k);
}
const seconds = (performance.now() - started) / 1e3;

const bits = new DataView(new ArrayBuffer(8));
function hex(x) {
    bits.setFloat64(0, x);
    return bits.getBigUint64(0).toString(16).padStart(16, "0");
}
const lines = [];
for (let k = 0; k <= points; k++) {
    const fields = [hex(k * h)];
    recorded.forEach(({ kind }, i) => {
        const x = values[k * recorded.length + i];
        fields.push(kind === "R" ? hex(x) : String(Math.trunc(x)));
    });
    lines.push(fields.join(" ") + "\n");
}
writeFileSync(out, lines.join(""));
process.stderr.write(`loop_seconds=${seconds.toFixed(9)}\n`);
