//! The web page (web/, docs/WEB.md) as a visitor and a page author meet it: troupe compiled to
//! WebAssembly (`scripts/web.sh` builds `web/pkg`), checked
//!
//! - in Node, against the demo bundle's goldens and against this (native) build on the same
//!   inputs (`tests/web/golden.mjs`);
//! - in headless Chromium (driven in real time by playwright-core, `tests/web/page.mjs`), the page
//!   served from 127.0.0.1 as any static server would: tokens come back, the partner is drawn in
//!   its colour where its joints project, a BVH given as a dropped file would be streams, and the
//!   page reports its load time, step latency and real-time factor.
//!
//! Without `web/pkg`, Node or playwright-core the checks are counted skips; under CI, where
//! `scripts/test.sh` installs them and builds the page first, failures. `TROUPE_BLESS=1` keeps
//! the screenshot docs/WEB.md shows.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use ndarray::Array2;
use ndarray_npy::read_npy;
use troupe::viewer::Camera;
use troupe::{Model, ReactorOptions};

use common::pictures::*;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// The built page's module and files, or `None` (a counted skip; a failure under CI).
fn web_pkg(test: &str) -> Option<PathBuf> {
    let pkg = repo("web/pkg");
    if pkg.join("troupe_web_bg.wasm").is_file() && pkg.join("armflow-demo.tar").is_file() {
        return Some(pkg);
    }
    assert!(
        std::env::var_os("CI").is_none_or(|v| v.is_empty()),
        "web/pkg is not built and CI is set: {test} is required there (scripts/test.sh runs \
         scripts/web.sh first)"
    );
    common::skip(test, "web/pkg not built (scripts/web.sh)");
    None
}

// ---------------------------------------------------------------------------------------------
// The module against the goldens and the native build.

/// What `golden.mjs` runs, natively: the same case, chunks and noise (tests/golden.rs's).
fn native_frames(model: &Model, bundle: &Path, case: &str) -> Vec<f32> {
    let golden = |name: &str| -> Array2<f32> {
        read_npy(bundle.join("golden").join(format!("{name}.npy"))).unwrap()
    };
    let (options, chunk) = match case {
        "default" => {
            let condition: ndarray::Array1<f32> =
                read_npy(bundle.join("golden/default_condition.npy")).unwrap();
            let options = ReactorOptions {
                condition: Some(condition.to_vec()),
                ..ReactorOptions::default()
            };
            (options, 1)
        }
        "cfg_steps_window" => {
            let options = ReactorOptions {
                steps: Some(2),
                cfg_scale: Some(2.5),
                context_capacity: Some(16),
                ..ReactorOptions::default()
            };
            (options, 5)
        }
        other => panic!("no case {other}"),
    };
    let mut session = model.session(options).unwrap();
    let (xi, eps) = (
        golden(&format!("{case}_xi")),
        golden(&format!("{case}_eps")),
    );
    common::queue_noise_rows(&mut session, &xi, &eps);
    common::run_chunked(&mut session, &golden("actor"), chunk).0
}

#[test]
fn the_module_matches_pytorch_and_the_native_build_on_the_goldens() {
    let test = "the_module_matches_pytorch_and_the_native_build_on_the_goldens";
    let Some(pkg) = web_pkg(test) else { return };
    if !common::tools_or_skip(test, &["node"], "nodejs") {
        return;
    }
    let bundle = repo("onnx/bundles/armflow-demo");
    let out = tempfile::tempdir().unwrap();
    let run = common::run_ok(
        Command::new("node")
            .arg(repo("tests/web/golden.mjs"))
            .args([&pkg, &bundle, &out.path().to_path_buf()]),
    );
    let model = Model::load(&bundle).unwrap();
    let lines = String::from_utf8_lossy(&run.stdout).to_string();
    let (mut cases, mut integers_checked) = (0, false);
    for line in lines.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        if let Some(refused) = v.get("refused") {
            // Out-of-range integers refused, not wrapped: every case golden.mjs tries.
            assert_eq!(refused, &v["of"], "{line}");
            integers_checked = true;
            continue;
        }
        let case = v["case"].as_str().unwrap();
        let wasm: Vec<f32> = std::fs::read(out.path().join(format!("{case}.f32")))
            .unwrap()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let native = native_frames(&model, &bundle, case);
        let scale = native.iter().fold(1f32, |m, v| m.max(v.abs()));
        let vs_native = common::max_abs_diff(&wasm, &native) / scale;
        let vs_pytorch = v["vs_pytorch"].as_f64().unwrap();
        println!(
            "{case}: {} tokens; wasm vs native {vs_native:.2e}, wasm vs PyTorch {vs_pytorch:.2e} \
             (max-abs difference / largest magnitude)",
            v["tokens"]
        );
        assert_eq!(v["tokens"].as_u64(), Some(48), "{case}: tokens");
        // Same graphs, same order of operations but other kernels (wasm SIMD vs AVX): rounding.
        assert!(
            vs_native <= 1e-5,
            "{case}: wasm and native differ by {vs_native}"
        );
        // The native build's own bound against PyTorch (tests/golden.rs, FRAME_TOL).
        assert!(
            vs_pytorch <= 1e-4,
            "{case}: wasm and PyTorch differ by {vs_pytorch}"
        );
        cases += 1;
    }
    assert_eq!(cases, 2, "golden.mjs ran {cases} cases:\n{lines}");
    assert!(integers_checked, "golden.mjs checked no integers:\n{lines}");
}

// ---------------------------------------------------------------------------------------------
// The page in Chromium.

/// The npm packages' folder (`TROUPE_NPM`, else `target/npm/node_modules`), which must hold
/// playwright-core (`scripts/test.sh` installs it): `None` (a counted skip, a failure under CI)
/// without it or Node.
fn npm_modules(test: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("TROUPE_NPM")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::target_dir().join("npm/node_modules"));
    if !common::tools_or_skip(test, &["node"], "nodejs") {
        return None;
    }
    if dir.join("playwright-core").is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("CI").is_none_or(|v| v.is_empty()),
        "{} lacks playwright-core and CI is set: {test} is required there (scripts/test.sh \
         installs it)",
        dir.display()
    );
    common::skip(
        test,
        "playwright-core not installed (scripts/test.sh installs it)",
    );
    None
}

/// What the page's tests need: the built page and the npm packages (see [`web_pkg`],
/// [`npm_modules`]).
fn page_tools(test: &str) -> Option<PathBuf> {
    web_pkg(test)?;
    npm_modules(test)
}

/// The page at `query`, served from 127.0.0.1 (`web/`, plus `extra` mounts), opened in headless
/// Chromium in real time until it has streamed (`tests/web/page.mjs`): its body's data
/// attributes, and with `shot` a screenshot of the 800 × 600 window.
fn open_page(
    modules: &Path,
    query: &str,
    extra: Vec<(String, PathBuf)>,
    shot: Option<&Path>,
) -> serde_json::Map<String, serde_json::Value> {
    open_page_with(modules, query, extra, shot, &[])
}

/// [`open_page`] with `tests/web/page.mjs`'s environment (`TROUPE_HOLD`, `TROUPE_TOKENS`).
fn open_page_with(
    modules: &Path,
    query: &str,
    extra: Vec<(String, PathBuf)>,
    shot: Option<&Path>,
    env: &[(&str, &str)],
) -> serde_json::Map<String, serde_json::Value> {
    let mut mounts = vec![("/".to_string(), repo("web"))];
    mounts.extend(extra);
    let base = common::static_server::serve(mounts);
    let mut cmd = Command::new("node");
    cmd.arg(repo("tests/web/page.mjs"))
        .arg(format!("{base}/index.html?{query}"))
        .env("TROUPE_NPM_MODULES", modules)
        .env("TROUPE_CHROMIUM", chromium())
        .envs(env.iter().copied());
    if let Some(shot) = shot {
        cmd.arg(shot);
    }
    let out = common::run_ok(&mut cmd);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let state = v["state"].as_object().unwrap().clone();
    assert_eq!(
        state.get("error"),
        None,
        "the page failed; its console: {}",
        v["console"]
    );
    state
}

fn text<'a>(state: &'a serde_json::Map<String, serde_json::Value>, key: &str) -> &'a str {
    state
        .get(key)
        .and_then(|v| v.as_str())
        .unwrap_or_else(|| panic!("the page has no data-{key}: {state:?}"))
}

fn number(state: &serde_json::Map<String, serde_json::Value>, key: &str) -> f64 {
    text(state, key).parse().unwrap()
}

/// The last picture's camera and people, as the page drew them.
struct Drawn {
    camera: Camera,
    actor: Vec<[f32; 3]>,
    partner: Vec<[f32; 3]>,
    width: f64,
    height: f64,
}

fn drawn(state: &serde_json::Map<String, serde_json::Value>) -> Drawn {
    let v: serde_json::Value = serde_json::from_str(text(state, "drawn")).unwrap();
    let joints = |key: &str| -> Vec<[f32; 3]> {
        let flat: Vec<f32> = v[key]
            .as_array()
            .unwrap_or_else(|| panic!("no {key} drawn"))
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect();
        flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    };
    let c = &v["camera"];
    let f = |k: &str| c[k].as_f64().unwrap() as f32;
    let target: Vec<f32> = c["target"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32)
        .collect();
    Drawn {
        camera: Camera {
            target: [target[0], target[1], target[2]],
            yaw_deg: f("yaw"),
            pitch_deg: f("pitch"),
            distance: f("distance"),
            fov_deg: f("fov"),
        },
        actor: joints("actor"),
        partner: joints("partner"),
        width: v["W"].as_f64().unwrap(),
        height: v["H"].as_f64().unwrap(),
    }
}

#[test]
fn the_page_streams_the_partner_and_draws_it_where_its_joints_are() {
    let test = "the_page_streams_the_partner_and_draws_it_where_its_joints_are";
    let Some(modules) = page_tools(test) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("page.png");
    // 480 actor frames at 120 fps: 4 s of the clip, 30 tokens.
    let state = open_page(
        &modules,
        "frames=480&rule=mirror&ui=0",
        Vec::new(),
        Some(&shot),
    );
    assert_eq!(text(&state, "ready"), "1");
    assert_eq!(text(&state, "rule"), "mirror");
    let tokens = number(&state, "tokens");
    assert!(tokens >= 25.0, "{tokens} tokens for 4 s of actor");
    let d = drawn(&state);
    assert_eq!((d.actor.len(), d.partner.len()), (22, 22));
    let image = decode_png(&shot);
    assert_eq!(
        (image.width as f64, image.height as f64),
        (d.width, d.height)
    );
    for (who, joints, colour) in [("actor", &d.actor, BLUE), ("partner", &d.partner, ORANGE)] {
        let px: Vec<[f64; 2]> = joints
            .iter()
            .map(|&p| project(&d.camera, p, d.width, d.height).expect("in front of the camera"))
            .collect();
        let seen = see(&image, colour, &px, 4);
        println!(
            "{who}: {} of 22 joints drawn in its colour, {} stray pixels",
            seen.joints_found, seen.stray
        );
        assert!(
            seen.joints_found >= 20,
            "{who}: {} joints seen",
            seen.joints_found
        );
        assert!(
            seen.stray < 50,
            "{who}: {} pixels away from its bones",
            seen.stray
        );
    }
    if std::env::var_os("TROUPE_BLESS").is_some() {
        let keep = repo("docs/images/web-page.png");
        open_page(&modules, "frames=480&rule=mirror", Vec::new(), Some(&keep));
    }
}

/// The page's own figures, measured in it: load, first reaction, step latency, real-time factor
/// (docs/WEB.md gives a run's).
#[test]
fn the_page_reports_its_figures() {
    let test = "the_page_reports_its_figures";
    let Some(modules) = page_tools(test) else {
        return;
    };
    // 8 s of the clip, as fast as the module goes.
    let state = open_page(&modules, "frames=960&rule=follow", Vec::new(), None);
    let (load, first, p50, p99, rtf) = (
        number(&state, "loadMs"),
        number(&state, "firstReactionMs"),
        number(&state, "p50Ms"),
        number(&state, "p99Ms"),
        number(&state, "rtf"),
    );
    println!(
        "in Chromium: load {load:.0} ms, first reaction {first:.0} ms after opening, step \
         p50 {p50:.2} ms, p99 {p99:.2} ms, {rtf:.1}x real time"
    );
    assert!(
        load > 0.0 && first >= load,
        "load {load}, first reaction {first}"
    );
    assert!(p50 > 0.0 && p99 >= p50 && rtf > 0.0);
}

/// A BVH dropped on the page becomes the actor and streams: Mixamo's rig, from bvhtoolbox's tests
/// (not troupe's skeleton, not troupe's file), dropped as a file from the desktop would be, and
/// the same file named by `?bvh=`.
#[test]
fn a_dropped_bvh_becomes_the_actor_and_streams() {
    let test = "a_dropped_bvh_becomes_the_actor_and_streams";
    let Some(modules) = page_tools(test) else {
        return;
    };
    let folder = common::pypi_sdist("bvhtoolbox==0.1.3").join("tests/example_files");
    let file = folder.join("test_freebvh.bvh");
    let dropped = open_page_with(
        &modules,
        "frames=200&rule=follow",
        Vec::new(),
        None,
        &[("TROUPE_DROP", file.to_str().unwrap())],
    );
    let named = open_page(
        &modules,
        "bvh=/files/test_freebvh.bvh&frames=200&rule=follow",
        vec![("/files/".into(), folder.clone())],
        None,
    );
    for (how, state) in [("dropped", &dropped), ("named", &named)] {
        assert_eq!(text(state, "actor"), "test_freebvh.bvh", "{how}");
        let tokens = number(state, "tokens");
        assert!(tokens >= 5.0, "{how}: {tokens} tokens");
        let d = drawn(state);
        // The actor drawn is the file's figure: a standing person's height, metres.
        let height = d.actor.iter().map(|p| p[1]).fold(f32::MIN, f32::max)
            - d.actor.iter().map(|p| p[1]).fold(f32::MAX, f32::min);
        println!("{how}: {tokens} tokens, the actor {height:.2} m tall");
        assert!((1.0..2.2).contains(&height), "{how}: actor {height} m tall");
    }
    // The same file, the same stream: the drop goes through the same reader and session.
    assert_eq!(text(&dropped, "drawn"), text(&named, "drawn"));
    // A rig the built-in names do not map (bvhtoolbox's mocapbank file: `LeftShoulder` is its
    // upper arm, no toes) is recognised by its shape and streams too, saying so.
    let other = open_page_with(
        &modules,
        "frames=200&rule=follow",
        Vec::new(),
        None,
        &[(
            "TROUPE_DROP",
            folder.join("test_mocapbank.bvh").to_str().unwrap(),
        )],
    );
    assert_eq!(text(&other, "actor"), "test_mocapbank.bvh");
    assert!(number(&other, "tokens") >= 5.0);
}

/// A file the page cannot use is said so in the status line, and the stage does not stay empty:
/// a BVH that is no humanoid (a chain of two joints) named by `?bvh=` leaves the default clip
/// playing, and dropped on a playing page leaves the current actor playing; a dropped FBX file
/// is said to be one (the page reads BVH; the library reads both).
#[test]
fn a_file_the_page_cannot_use_is_said_so_and_the_stage_plays_on() {
    let test = "a_file_the_page_cannot_use_is_said_so_and_the_stage_plays_on";
    let Some(modules) = page_tools(test) else {
        return;
    };
    let folder = tempfile::tempdir().unwrap();
    let chain = folder.path().join("chain.bvh");
    std::fs::write(
        &chain,
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition \
         Zrotation Xrotation Yrotation\n JOINT Spine\n {\n  OFFSET 0 10 0\n  CHANNELS 3 \
         Xrotation Yrotation Zrotation\n  End Site\n  {\n   OFFSET 0 5 0\n  }\n }\n}\nMOTION\n\
         Frames: 2\nFrame Time: 0.0333333\n0 90 0 0 0 0 0 0 0\n0 90 0 0 0 0 0 0 0\n",
    )
    .unwrap();
    let named = open_page(
        &modules,
        "bvh=/files/chain.bvh&frames=200&rule=follow",
        vec![("/files/".into(), folder.path().to_path_buf())],
        None,
    );
    let dropped = open_page_with(
        &modules,
        "frames=200&rule=follow",
        Vec::new(),
        None,
        &[("TROUPE_DROP", chain.to_str().unwrap())],
    );
    for (how, state, then) in [
        ("named", &named, "playing the default clip instead"),
        ("dropped", &dropped, "the current actor plays on"),
    ] {
        let said = text(state, "refused");
        println!("{how}: {said}");
        assert!(
            said.starts_with("chain.bvh cannot be used (") && said.ends_with(then),
            "{how}: {said}"
        );
        assert!(
            said.contains("left_hip"),
            "{how}: the reason is given: {said}"
        );
        assert_ne!(text(state, "actor"), "chain.bvh", "{how}");
        let tokens = number(state, "tokens");
        assert!(tokens >= 5.0, "{how}: {tokens} tokens");
        let d = drawn(state);
        let height = d.actor.iter().map(|p| p[1]).fold(f32::MIN, f32::max)
            - d.actor.iter().map(|p| p[1]).fold(f32::MAX, f32::min);
        assert!((1.0..2.2).contains(&height), "{how}: actor {height} m tall");
    }
    // The same default clip plays either way.
    assert_eq!(text(&named, "actor"), text(&dropped, "actor"));
    let fbx = open_page_with(
        &modules,
        "frames=200&rule=follow",
        Vec::new(),
        None,
        &[(
            "TROUPE_DROP",
            repo("tests/data/ascii_body.fbx").to_str().unwrap(),
        )],
    );
    let said = text(&fbx, "refused");
    assert!(
        said.starts_with(
            "ascii_body.fbx cannot be used (ascii_body.fbx is an FBX file: this page reads BVH"
        ) && said.ends_with("the current actor plays on"),
        "{said}"
    );
    assert!(number(&fbx, "tokens") >= 5.0);
}

/// The steered actor goes where the arrow keys send it: live, 4 s of stream with ← held turn it
/// away from where it goes with no key, and the partner keeps streaming.
#[test]
fn the_visitor_steers_the_actor_with_the_arrow_keys() {
    let test = "the_visitor_steers_the_actor_with_the_arrow_keys";
    let Some(modules) = page_tools(test) else {
        return;
    };
    let root = |hold: Option<&str>| {
        let mut env = vec![("TROUPE_TOKENS", "30")];
        if let Some(key) = hold {
            env.push(("TROUPE_HOLD", key));
        }
        let state = open_page_with(&modules, "source=steer&rule=follow", Vec::new(), None, &env);
        assert!(text(&state, "actor").contains("steer"));
        let d = drawn(&state);
        println!("held {hold:?}: actor's root at {:?}", d.actor[0]);
        [d.actor[0][0], d.actor[0][2]]
    };
    let (straight, left) = (root(None), root(Some("ArrowLeft")));
    let apart = ((straight[0] - left[0]).powi(2) + (straight[1] - left[1]).powi(2)).sqrt();
    assert!(
        apart > 0.3,
        "holding ← moved the actor's root by only {apart} m"
    );
}

/// The JavaScript sample of `docs/WEB.md` runs in Node against the built module
/// (`tests/common/samples.rs`: its setup gives Node the page's `fetch`, reading files), from a
/// folder that holds the module as `pkg/`, where the sample's paths lead.
#[test]
fn the_javascript_samples_of_the_docs_run() {
    let test = "the_javascript_samples_of_the_docs_run";
    let Some(pkg) = web_pkg(test) else { return };
    if !common::tools_or_skip(test, &["node"], "nodejs") {
        return;
    }
    let samples = common::samples::samples(&repo(""), "js");
    assert!(!samples.is_empty());
    let scratch = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(&pkg, scratch.path().join("pkg")).unwrap();
    for (i, sample) in samples.iter().enumerate() {
        assert!(
            sample.skip.is_none(),
            "{sample:?}: a JavaScript sample is run"
        );
        let script = scratch.path().join(format!("sample_{i}.mjs"));
        std::fs::write(&script, format!("{}{}", sample.setup, sample.code)).unwrap();
        let out = Command::new("node")
            .arg(&script)
            .current_dir(scratch.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "JavaScript sample {}:{}: {}{}",
            sample.file,
            sample.line,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
