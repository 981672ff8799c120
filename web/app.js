// The live partner: troupe's demo model, compiled to WebAssembly, reacting in the page to an
// actor that plays here and now. No server logic: the page, the module, the bundle and the clip
// are files beside this one (scripts/web.sh puts the built ones in pkg/).
//
// Query: ?rule=NAME  ?source=clip|steer  ?bvh=URL (a BVH streamed as a dropped file would be)
//        ?ui=0 (the people alone)  ?seed=N
//        ?frames=N: stream N actor frames as fast as the module goes, one token's worth a call,
//        then hold the last picture (deterministic stills; the real-time factor at full speed)
import init, { WebModel, WebClip, jointNames, jointParents } from "./pkg/troupe_web.js";

const params = new URLSearchParams(window.location.search);
const ACTOR_COLOUR = "#1f77b4"; // troupe's palette (src/viewer/scene.rs): person 0, person 1
const PARTNER_COLOUR = "#ff7f0e";
const KEEP_S = 20;              // seconds of the actor kept, to draw it as of the partner's frame
const MAX_BATCH_S = 0.5;        // at most this much actor motion per step call
const FIXED_FRAMES = Number.parseInt(params.get("frames") ?? "", 10);
const $ = (id) => document.getElementById(id);
if (params.get("ui") === "0") document.body.classList.add("bare");
$("actor-swatch").style.background = ACTOR_COLOUR;
$("partner-swatch").style.background = PARTNER_COLOUR;

// What the tests and a curious visitor can read: the body's data attributes and window.troupeWeb.
const state = document.body.dataset;
function status(text, error = false) {
  $("status").textContent = text;
  $("status").classList.toggle("error", error);
  if (error) state.error = text;
}
// A visitor's file the page cannot use: said in the status line (in red), while the page plays on.
function refused(text) {
  $("status").textContent = text;
  $("status").classList.add("error");
  state.refused = text;
}

// ---- actors: frames of 22 joints, metres, +Y up, at their own rate ---------------------------

// A .npy of float32 [frames, 22, 3] (metres, +Z up, as troupe's test clips are) turned +Y up.
function clipFromNpy(buffer, fps) {
  const bytes = new Uint8Array(buffer);
  const major = bytes[6];
  const view = new DataView(buffer);
  const headerLen = major === 1 ? view.getUint16(8, true) : view.getUint32(8, true);
  const start = major === 1 ? 10 : 12;
  const header = new TextDecoder().decode(bytes.subarray(start, start + headerLen));
  if (!header.includes("'<f4'") || header.includes("'fortran_order': True")) {
    throw new Error("the clip is not little-endian float32 in C order");
  }
  const data = new Float32Array(buffer.slice(start + headerLen));
  const out = new Float32Array(data.length);
  for (let i = 0; i < data.length; i += 3) {
    out[i] = data[i];          // (x, y, z) z-up -> (x, z, -y) y-up (InterGen's trans_matrix)
    out[i + 1] = data[i + 2];
    out[i + 2] = -data[i + 1];
  }
  return { name: "the CMU clip", positions: out, frames: out.length / 66, fps };
}

// Plays a clip in a loop; each loop starts where the last one ended, so the actor never jumps.
class LoopedClip {
  constructor(clip) {
    this.clip = clip;
    this.name = clip.name;
    this.fps = clip.fps;
  }
  // Frame `i` of the endless stream.
  frame(i) {
    const n = this.clip.frames, p = this.clip.positions;
    const loop = Math.floor(i / n), f = i % n;
    const out = p.slice(f * 66, f * 66 + 66);
    if (loop > 0) {
      // The root's travel over one pass, added once per pass (floor plane only).
      const dx = p[(n - 1) * 66] - p[0], dz = p[(n - 1) * 66 + 2] - p[2];
      for (let j = 0; j < 22; j++) {
        out[j * 3] += loop * dx;
        out[j * 3 + 2] += loop * dz;
      }
    }
    return out;
  }
}

// The clip driven by the keyboard: each frame's motion relative to the body (its step, its own
// turn) is replayed from where the actor is, with the visitor's turning added.
class SteeredClip {
  constructor(clip) {
    this.clip = clip;
    this.name = "you steer the CMU clip";
    this.fps = clip.fps;
    this.turn = 0;       // rad/s, from the arrow keys
    this.pace = 1;       // times the clip's own travel
    this.at = [clip.positions[0], clip.positions[2]];
    this.heading = this.headingOf(0);
    this.next = 0;
  }
  headingOf(f) {
    const p = this.clip.positions, o = f * 66;
    // Facing: across the hips (left hip 1, right hip 2) turned a quarter about +Y.
    const ax = p[o + 1 * 3] - p[o + 2 * 3], az = p[o + 1 * 3 + 2] - p[o + 2 * 3 + 2];
    return Math.atan2(-az, ax);
  }
  frame(i) {
    if (i !== this.next) throw new Error("a steered actor is played in order");
    const n = this.clip.frames, p = this.clip.positions, f = i % n;
    const h = this.headingOf(f); // the clip's own heading at f
    if (i > 0 && f > 0) {
      const o0 = (f - 1) * 66, o1 = f * 66;
      const h0 = this.headingOf(f - 1);
      // The step in the body's frame at f - 1, turned to the actor's heading now.
      const dx = p[o1] - p[o0], dz = p[o1 + 2] - p[o0 + 2];
      const c = Math.cos(this.heading - h0), s = Math.sin(this.heading - h0);
      this.at[0] += this.pace * (c * dx + s * dz);
      this.at[1] += this.pace * (-s * dx + c * dz);
      let dh = h - h0;
      dh = Math.atan2(Math.sin(dh), Math.cos(dh));
      this.heading += dh + this.turn / this.fps;
    }
    this.next = i + 1;
    const o = f * 66;
    const c = Math.cos(this.heading - h), s = Math.sin(this.heading - h);
    const out = new Float32Array(66);
    for (let j = 0; j < 22; j++) {
      const x = p[o + j * 3] - p[o], z = p[o + j * 3 + 2] - p[o + 2];
      out[j * 3] = this.at[0] + c * x + s * z;
      out[j * 3 + 1] = p[o + j * 3 + 1];
      out[j * 3 + 2] = this.at[1] - s * x + c * z;
    }
    return out;
  }
}

// ---- the stream ----------------------------------------------------------------------------

let model = null, session = null, source = null, cmu = null;
let rule = null;
let startedAt = null;        // performance.now() when the current actor began
let fed = 0;                 // actor frames given to the session
let actorFrames = [];        // { t: seconds, pos } of the frames fed, for drawing
let partner = null;          // the newest partner frame: { k: its index at the model's rate, pos }
const timing = { calls: [], streamS: 0, computeS: 0, firstReactionMs: null };

function newSession() {
  const seed = BigInt(Number.parseInt(params.get("seed") ?? "0", 10) || 0);
  const s = model.session(seed, rule);
  s.setJointsFormat("m", "y", source.fps);
  // The streaming demo's clean-ups (examples/stream.rs): root smoothing, the guard, foot lock,
  // recentring.
  s.setRootSmoothing(true, 0.1);
  s.setPenetrationGuard(true, 0.25, 10.0);
  s.setFootLock(true);
  s.armflowSetRecentring(true, 1.0);
  if (session) session.free();
  session = s;
  startedAt = null;
  fed = 0;
  actorFrames = [];
  partner = null;
  timing.calls = [];
  timing.streamS = 0;
  timing.computeS = 0;
  state.tokens = "0";
  delete state.done;
}

function setSource(next) {
  source = next;
  $("actor-name").textContent = "actor: " + next.name;
  state.actor = next.name;
  newSession();
}

function percentile(values, q) {
  if (values.length === 0) return NaN;
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))];
}

// Feeds the actor frames that are due by `now` and keeps what comes back.
function advance(now) {
  if (startedAt === null) startedAt = now;
  let n;
  if (FIXED_FRAMES > 0) {
    // One token's worth of the actor's frames a call, until N.
    const perToken = Math.round((model.framesPerToken * source.fps) / model.fps);
    n = Math.min(perToken, FIXED_FRAMES - fed);
    if (n <= 0) {
      state.done = "1";
      return;
    }
  } else {
    const due = Math.floor(((now - startedAt) / 1000) * source.fps);
    n = Math.min(due - fed, Math.ceil(MAX_BATCH_S * source.fps));
    if (n <= 0) return;
  }
  const batch = new Float32Array(n * 66);
  for (let k = 0; k < n; k++) {
    const pos = source.frame(fed + k);
    batch.set(pos, k * 66);
    actorFrames.push({ t: (fed + k) / source.fps, pos });
  }
  const t0 = performance.now();
  const out = session.stepJoints(batch);
  const ms = performance.now() - t0;
  fed += n;
  if (out.length > 0) {
    const k = (partner ? partner.k + 1 : 0) + out.length / 66 - 1;
    partner = { k, pos: out.subarray(out.length - 66) };
  }
  // Warm calls only: the first token pays for the caches' first use.
  if (session.tokensGenerated > 1) {
    timing.streamS += n / source.fps;
    timing.computeS += ms / 1000;
    if (out.length > 0) timing.calls.push(ms);
    if (timing.calls.length > 2000) timing.calls.splice(0, 1000); // the recent ones
  }
  if (out.length > 0 && timing.firstReactionMs === null) {
    timing.firstReactionMs = performance.now();
  }
  // Forget what is too old to draw.
  const oldest = fed / source.fps - KEEP_S;
  while (actorFrames.length > 0 && actorFrames[0].t < oldest) actorFrames.shift();
}

function showStats() {
  const tokens = session.tokensGenerated;
  $("tokens").textContent = String(tokens);
  state.tokens = String(tokens);
  if (timing.calls.length > 0) {
    const p50 = percentile(timing.calls, 0.5), p99 = percentile(timing.calls, 0.99);
    const rtf = timing.streamS / Math.max(1e-9, timing.computeS);
    $("latency").textContent = p50.toFixed(2) + " / " + p99.toFixed(2) + " ms";
    $("rtf").textContent = rtf.toFixed(0) + "× real time";
    state.p50Ms = p50.toFixed(3);
    state.p99Ms = p99.toFixed(3);
    state.rtf = rtf.toFixed(1);
  }
  if (timing.firstReactionMs !== null && !state.firstReactionMs) {
    state.firstReactionMs = timing.firstReactionMs.toFixed(0);
    $("first").textContent = (timing.firstReactionMs / 1000).toFixed(2) + " s after opening";
  }
}

// ---- drawing: the player's own (pkg/draw.js is src/viewer/draw.js) --------------------------

const canvas = $("view");
const ctx = canvas.getContext("2d");
let parents = null, head = -1;
const cam = { target: [0, 0.9, 0], yaw: 30, pitch: 12, distance: 6, fov: 45 };
let lastDrawn = null;

function render() {
  const W = window.innerWidth, H = window.innerHeight, dpr = window.devicePixelRatio || 1;
  if (canvas.width !== Math.round(W * dpr) || canvas.height !== Math.round(H * dpr)) {
    canvas.width = Math.round(W * dpr);
    canvas.height = Math.round(H * dpr);
  }
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  // The partner's newest frame and the actor at the same instant (both drawn as of then).
  const bodies = [];
  let actorPos = null, partnerPos = null;
  if (partner) {
    partnerPos = partner.pos;
    const t = partner.k / model.fps;
    const i = actorFrames.findIndex((f) => f.t >= t - 0.5 / source.fps);
    actorPos = (i >= 0 ? actorFrames[i] : actorFrames[actorFrames.length - 1]).pos;
  } else if (actorFrames.length > 0) {
    actorPos = actorFrames[actorFrames.length - 1].pos;
  }
  if (actorPos) bodies.push({ colour: ACTOR_COLOUR, pos: actorPos, base: 0 });
  if (partnerPos) bodies.push({ colour: PARTNER_COLOUR, pos: partnerPos, base: 0 });
  // The camera follows the pair (the midpoint of their roots): slowly, or at once for stills.
  const follow = FIXED_FRAMES > 0 ? 1 : 0.1;
  const roots = bodies.map((b) => [b.pos[0], b.pos[2]]);
  if (roots.length > 0) {
    const mx = roots.reduce((s, r) => s + r[0], 0) / roots.length;
    const mz = roots.reduce((s, r) => s + r[1], 0) / roots.length;
    cam.target[0] += follow * (mx - cam.target[0]);
    cam.target[2] += follow * (mz - cam.target[2]);
  }
  const g = 1.0;
  const [cx, cz] = [Math.round(cam.target[0]), Math.round(cam.target[2])];
  const stage = { floor: 0, grid: [cx - 6, cx + 6, cz - 6, cz + 6, g], parents, head };
  TroupeDraw.draw(ctx, W, H, cam, stage, bodies);
  lastDrawn = {
    W, H, camera: { ...cam, target: cam.target.slice() },
    actor: actorPos && Array.from(actorPos), partner: partnerPos && Array.from(partnerPos),
  };
  state.drawn = JSON.stringify(lastDrawn);
}

function tick(now) {
  if (session) {
    try {
      advance(now);
      showStats();
    } catch (e) {
      status(String(e.message ?? e), true);
      session = null;
    }
  }
  if (parents) render();
  window.requestAnimationFrame(tick);
}

// ---- controls ------------------------------------------------------------------------------

$("rule").addEventListener("change", () => {
  rule = $("rule").value;
  session.setCondition(model, rule); // from the next token on, the stream goes on
  state.rule = rule;
});
$("source").addEventListener("change", () => {
  const v = $("source").value;
  if (v === "clip") setSource(new LoopedClip(cmu));
  if (v === "steer") setSource(new SteeredClip(cmu));
});
window.addEventListener("keydown", (e) => {
  if (!(source instanceof SteeredClip)) return;
  if (e.key === "ArrowLeft") source.turn = 1.5;
  else if (e.key === "ArrowRight") source.turn = -1.5;
  else if (e.key === "ArrowUp") source.pace = Math.min(2, source.pace + 0.25);
  else if (e.key === "ArrowDown") source.pace = Math.max(0, source.pace - 0.25);
  else return;
  e.preventDefault();
});
window.addEventListener("keyup", (e) => {
  if (source instanceof SteeredClip && (e.key === "ArrowLeft" || e.key === "ArrowRight")) {
    source.turn = 0;
  }
});

// A BVH (dropped, chosen, or named by ?bvh=) read by troupe's reader becomes the actor.
async function useBvh(name, buffer) {
  try {
    const clip = WebClip.fromBvh(new Uint8Array(buffer), name);
    const actor = { name, positions: clip.positions, frames: clip.frames, fps: clip.fps };
    const inferred = clip.inferred;
    clip.free();
    $("source").querySelector("option[value=bvh]").disabled = false;
    $("source").value = "bvh";
    setSource(new LoopedClip(actor));
    status(
      `${name}: ${actor.frames} frames at ${actor.fps.toFixed(0)} fps` +
        (inferred.length ? `; inferred: ${inferred.join("; ")}` : "")
    );
  } catch (e) {
    // The stage never stays empty: with no actor yet (a `?bvh=` that cannot be used), the
    // default clip plays; otherwise the current actor plays on.
    let then = "the current actor plays on";
    if (!source) {
      $("source").value = "clip";
      setSource(new LoopedClip(cmu));
      then = "playing the default clip instead";
    }
    refused(`${name} cannot be used (${e.message ?? e}); ${then}`);
  }
}
window.addEventListener("dragover", (e) => {
  e.preventDefault();
  document.body.classList.add("dragging");
});
window.addEventListener("dragleave", () => document.body.classList.remove("dragging"));
window.addEventListener("drop", async (e) => {
  e.preventDefault();
  document.body.classList.remove("dragging");
  const file = e.dataTransfer.files[0];
  if (file) useBvh(file.name, await file.arrayBuffer());
});
$("file").addEventListener("change", async () => {
  const file = $("file").files[0];
  if (file) useBvh(file.name, await file.arrayBuffer());
});

// Orbit by dragging, zoom with the wheel.
let drag = null;
canvas.addEventListener("pointerdown", (e) => {
  drag = { x: e.clientX, y: e.clientY };
  canvas.setPointerCapture(e.pointerId);
});
canvas.addEventListener("pointermove", (e) => {
  if (!drag) return;
  cam.yaw -= (e.clientX - drag.x) * 0.4;
  cam.pitch = Math.min(89, Math.max(-89, cam.pitch + (e.clientY - drag.y) * 0.3));
  drag = { x: e.clientX, y: e.clientY };
});
canvas.addEventListener("pointerup", () => (drag = null));
canvas.addEventListener(
  "wheel",
  (e) => {
    e.preventDefault();
    cam.distance = Math.min(100, Math.max(0.5, cam.distance * Math.exp(e.deltaY * 0.001)));
  },
  { passive: false }
);

window.troupeWeb = {
  drawn: () => lastDrawn,
  stats: () => ({ ...timing, calls: timing.calls.length }),
  model: () => model,
};

// ---- start ---------------------------------------------------------------------------------

async function fetchBytes(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return r.arrayBuffer();
}

async function start() {
  try {
    const t0 = performance.now();
    const [, bundle, npy] = await Promise.all([
      init({ module_or_path: "pkg/troupe_web_bg.wasm" }),
      fetchBytes("pkg/armflow-demo.tar"),
      fetchBytes("pkg/cmu-playground-120fps.npy"),
    ]);
    model = new WebModel(new Uint8Array(bundle), "armflow-demo.tar");
    const loadMs = performance.now() - t0;
    state.loadMs = loadMs.toFixed(0);
    $("load").textContent = `${loadMs.toFixed(0)} ms (module, bundle, clip)`;
    parents = Array.from(jointParents());
    head = jointNames().indexOf("head");
    cmu = clipFromNpy(npy, 120);
    for (const name of model.conditionNames()) {
      const o = new Option(name, name);
      o.title = model.conditionAbout(name);
      $("rule").add(o);
    }
    rule = params.get("rule") ?? model.conditionNames()[0] ?? null;
    $("rule").value = rule;
    state.rule = rule;
    $("rule").disabled = false;
    $("source").disabled = false;
    status(`${model.name}: ${model.fps} fps, ${model.framesPerToken} frames a token, ` +
      `${model.jointsLatencyFrames} frames of latency`);
    if (params.get("bvh")) {
      const url = params.get("bvh");
      await useBvh(url.split("/").pop(), await fetchBytes(url));
    } else {
      const wanted = params.get("source") === "steer" ? "steer" : "clip";
      $("source").value = wanted;
      setSource(wanted === "steer" ? new SteeredClip(cmu) : new LoopedClip(cmu));
    }
    state.ready = "1";
  } catch (e) {
    status(String(e.message ?? e), true);
  }
}

window.requestAnimationFrame(tick);
start();
