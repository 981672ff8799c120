// The WebAssembly module (web/pkg, built by scripts/web.sh) on the demo bundle's committed
// goldens, in Node, through the same bindings the page uses: both ARMFlow golden cases, the
// goldens' noise queued, the actor fed in the chunks tests/golden.rs feeds. For each case it
// writes the reactor's frames to OUT/<case>.f32 (raw little-endian float32) and prints one JSON
// line: the frames' largest difference from the PyTorch reference over its largest magnitude,
// the figure tests/golden.rs holds the native build to. tests/web.rs compares the frames with the
// native build's. Last, a line {"refused": N, "of": M}: integers out of range tried against the
// module (seeds, capacities, steps), each of which must be refused.
//
//   node tests/web/golden.mjs WEB_PKG BUNDLE_DIR OUT
import { readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { pathToFileURL } from "node:url";

const [pkg, bundle, out] = process.argv.slice(2);
const web = await import(pathToFileURL(join(pkg, "troupe_web.js")).href);
web.initSync({ module: readFileSync(join(pkg, "troupe_web_bg.wasm")) });

// A little-endian float32 .npy in C order: { shape, data }.
function npy(path) {
  const b = readFileSync(path);
  const major = b[6];
  const len = major === 1 ? b.readUInt16LE(8) : b.readUInt32LE(8);
  const start = major === 1 ? 10 : 12;
  const header = b.subarray(start, start + len).toString("latin1");
  if (!header.includes("'<f4'") || header.includes("True")) {
    throw new Error(`${path}: not little-endian float32 in C order`);
  }
  const shape = header.match(/\(([^)]*)\)/)[1].split(",").filter((s) => s.trim()).map(Number);
  const bytes = b.subarray(start + len);
  const data = new Float32Array(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length));
  return { shape, data };
}
const golden = (name) => npy(join(bundle, "golden", `${name}.npy`));

const model = new web.WebModel(readFileSync(join(pkg, "armflow-demo.tar")), "armflow-demo.tar");
const actor = golden("actor");
const [frames, dim] = actor.shape;
if (dim !== model.frameDim) throw new Error(`actor frames of ${dim}, model takes ${model.frameDim}`);

const cases = {
  // tests/golden.rs: default_case_matches_pytorch, cfg_multistep_sliding_window_matches_pytorch
  default: { chunk: 1, steps: 1, cfg: 1, capacity: undefined, condition: golden("default_condition").data },
  cfg_steps_window: { chunk: 5, steps: 2, cfg: 2.5, capacity: 16, condition: undefined },
};

for (const [name, c] of Object.entries(cases)) {
  const session = model.session(0n, undefined, c.capacity);
  session.setConditionVector(c.condition);
  session.setSteps(c.steps);
  session.setCfgScale(c.cfg);
  const xi = golden(`${name}_xi`), eps = golden(`${name}_eps`);
  const latent = model.latentDim;
  for (let t = 0; t < xi.shape[0]; t++) {
    session.armflowQueueNoise(xi.data.subarray(t * latent, (t + 1) * latent),
      eps.data.subarray(t * latent, (t + 1) * latent));
  }
  const got = [];
  for (let f = 0; f < frames; f += c.chunk) {
    const n = Math.min(c.chunk, frames - f);
    got.push(...session.step(actor.data.subarray(f * dim, (f + n) * dim)));
  }
  const want = golden(`${name}_frames`).data;
  if (got.length !== want.length) throw new Error(`${name}: ${got.length} floats, golden ${want.length}`);
  let diff = 0, scale = 1;
  for (let i = 0; i < want.length; i++) {
    diff = Math.max(diff, Math.abs(got[i] - want[i]));
    scale = Math.max(scale, Math.abs(want[i]));
  }
  writeFileSync(join(out, `${name}.f32`), Buffer.from(new Float32Array(got).buffer));
  console.log(JSON.stringify({
    case: name, tokens: session.tokensGenerated, floats: got.length, vs_pytorch: diff / scale,
  }));
  session.free();
}

// Integers out of range are refused, not wrapped (a plain u32 parameter took 2 ** 32 + 1 as 1).
const refusals = [
  ["seed 2n ** 64n", () => model.session(2n ** 64n)],
  ["seed -1n", () => model.session(-1n)],
  ["seed -1", () => model.session(-1)],
  ["seed 1.5", () => model.session(1.5)],
  ["seed '7'", () => model.session("7")],
  ["capacity 2 ** 32 + 64", () => model.session(0n, undefined, 2 ** 32 + 64)],
  ["capacity 16.5", () => model.session(0n, undefined, 16.5)],
  ["steps 2 ** 32 + 1", () => model.session(0n).setSteps(2 ** 32 + 1)],
  ["steps -1", () => model.session(0n).setSteps(-1)],
  ["steps NaN", () => model.session(0n).setSteps(NaN)],
];
let refused = 0;
for (const [what, call] of refusals) {
  try {
    call();
  } catch (e) {
    if (!/whole number|BigInt/.test(String(e))) throw new Error(`${what}: refused with ${e}`);
    refused += 1;
    continue;
  }
  throw new Error(`${what} was accepted`);
}
// In range, as BigInt or Number, they are taken.
model.session(2n ** 64n - 1n, undefined, 16).setSteps(2);
model.session(7).free();
console.log(JSON.stringify({ refused, of: refusals.length }));
model.free();
