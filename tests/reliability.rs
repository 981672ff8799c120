//! Hostile files and extreme inputs (issue 16): each case once aborted the process, hung, read
//! outside the bundle, returned non-finite motion or broke the session. Each must now give a
//! clear error before anything is allocated, and leave the session usable.

mod common;

use std::path::Path;
use std::sync::mpsc;
use std::time::Duration;

use common::*;
use ndarray::Array2;
use troupe::{ClipOptions, Error, Model, Reactor, ReactorOptions, TokenNoise, LIMITS};

/// Loads `path` on another thread; fails the test if the load has not returned in 60 s (a hang)
/// rather than hanging the suite.
fn load_without_hanging(path: &Path) -> Result<Model, Error> {
    let (tx, rx) = mpsc::channel();
    let path = path.to_path_buf();
    std::thread::spawn(move || tx.send(Model::load(&path)).ok());
    rx.recv_timeout(Duration::from_secs(60))
        .expect("the load returned instead of blocking")
}

fn tar_header(name: &str, kind: tar::EntryType, size: u64) -> [u8; 512] {
    let mut header = tar::Header::new_gnu();
    // The raw name field: `set_path` refuses the `..` a hostile archive may hold.
    header.as_old_mut().name[..name.len()].copy_from_slice(name.as_bytes());
    header.set_entry_type(kind);
    header.set_size(size);
    header.set_mode(0o644);
    header.set_cksum();
    *header.as_bytes()
}

/// An archive of raw 512-byte blocks: the headers and data given, then the end marker.
fn raw_archive(blocks: &[&[u8]]) -> Vec<u8> {
    let mut out = Vec::new();
    for block in blocks {
        out.extend_from_slice(block);
        out.resize(out.len().div_ceil(512) * 512, 0);
    }
    out.extend_from_slice(&[0u8; 1024]);
    out
}

#[test]
fn tar_members_declaring_huge_sizes_are_refused_before_allocating() {
    let huge = tar_header("troupe.json", tar::EntryType::Regular, 1 << 50);
    let bytes = raw_archive(&[&huge, b"{}"]);
    let e = Model::from_archive_bytes(&bytes, "huge.troupe").unwrap_err();
    assert!(
        e.to_string().contains("declares 1125899906842624 bytes"),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("huge.troupe");
    std::fs::write(&file, &bytes).unwrap();
    let e = Model::load(&file).unwrap_err();
    assert!(e.to_string().contains("declares"), "{e}");

    // A PAX extended header overriding the member's size with 10^15.
    let record = "25 size=1000000000000000\n";
    assert_eq!(record.len(), 25);
    let pax = tar_header("pax", tar::EntryType::XHeader, record.len() as u64);
    let small = tar_header("troupe.json", tar::EntryType::Regular, 2);
    let bytes = raw_archive(&[&pax, record.as_bytes(), &small, b"{}"]);
    let e = Model::from_archive_bytes(&bytes, "pax.troupe").unwrap_err();
    assert!(e.to_string().contains("1000000000000000"), "{e}");
}

#[test]
fn archives_with_links_devices_or_repeated_members_are_refused() {
    let manifest = std::fs::read(bundle_dir().join("troupe.json")).unwrap();
    let member = tar_header(
        "troupe.json",
        tar::EntryType::Regular,
        manifest.len() as u64,
    );
    let twice = raw_archive(&[&member, &manifest, &member, &manifest]);
    let e = Model::from_archive_bytes(&twice, "twice.troupe").unwrap_err();
    assert!(e.to_string().contains("`troupe.json` appears twice"), "{e}");

    for kind in [
        tar::EntryType::Symlink,
        tar::EntryType::Link,
        tar::EntryType::Char,
        tar::EntryType::Fifo,
    ] {
        let link = tar_header("velocity.onnx", kind, 0);
        let e = Model::from_archive_bytes(&raw_archive(&[&link]), "links.troupe").unwrap_err();
        assert!(
            e.to_string().contains("only regular files"),
            "{kind:?}: {e}"
        );
    }
    let escape = tar_header("../troupe.json", tar::EntryType::Regular, 2);
    let e = Model::from_archive_bytes(&raw_archive(&[&escape, b"{}"]), "escape.troupe");
    assert!(
        e.unwrap_err()
            .to_string()
            .contains("not a plain relative path"),
        "a member outside the bundle"
    );
}

#[cfg(unix)]
#[test]
fn bundle_files_outside_the_directory_devices_and_fifos_are_refused_without_blocking() {
    use std::os::unix::fs::symlink;

    // A graph that is a symlink to a file outside the bundle.
    let outside = tempfile::tempdir().unwrap();
    let dir = bundle_copy();
    let graph = dir.path().join("velocity.onnx");
    std::fs::rename(&graph, outside.path().join("velocity.onnx")).unwrap();
    symlink(outside.path().join("velocity.onnx"), &graph).unwrap();
    let e = load_without_hanging(dir.path()).unwrap_err();
    assert!(
        e.to_string().contains("outside the bundle directory"),
        "{e}"
    );

    // A symlink inside the bundle is followed.
    let dir = bundle_copy();
    let graph = dir.path().join("velocity.onnx");
    std::fs::rename(&graph, dir.path().join("velocity.real.onnx")).unwrap();
    symlink("velocity.real.onnx", &graph).unwrap();
    load_without_hanging(dir.path()).expect("an in-bundle symlink loads");

    // Devices: never read (they never end).
    for device in ["/dev/zero", "/dev/urandom"] {
        for name in ["velocity.onnx", "troupe.json"] {
            let dir = bundle_copy();
            std::fs::remove_file(dir.path().join(name)).unwrap();
            symlink(device, dir.path().join(name)).unwrap();
            let e = load_without_hanging(dir.path()).unwrap_err();
            assert!(
                e.to_string().contains("outside the bundle"),
                "{name} -> {device}: {e}"
            );
        }
        let e = load_without_hanging(Path::new(device)).unwrap_err();
        assert!(
            e.to_string().contains("not a regular file"),
            "{device}: {e}"
        );
    }

    // FIFOs as graph, manifest, or the bundle itself: refused at once, no writer awaited.
    let fifo = |path: &Path| {
        let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    };
    for name in ["velocity.onnx", "troupe.json"] {
        let dir = bundle_copy();
        std::fs::remove_file(dir.path().join(name)).unwrap();
        fifo(&dir.path().join(name));
        let e = load_without_hanging(dir.path()).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{name}: {e}");
    }
    let dir = tempfile::tempdir().unwrap();
    fifo(&dir.path().join("bundle.troupe"));
    let e = load_without_hanging(&dir.path().join("bundle.troupe")).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
}

#[test]
fn oversized_bundle_files_are_refused_before_being_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sparse.troupe");
    let file = std::fs::File::create(&path).unwrap();
    file.set_len(LIMITS.max_bundle_bytes + 1).unwrap();
    let e = load_without_hanging(&path).unwrap_err();
    assert!(e.to_string().contains("above troupe's limit"), "{e}");
    // Within the limit, a file of zeros ends at its first (empty) tar block: nothing more is read.
    file.set_len(3 << 29).unwrap();
    let e = load_without_hanging(&path).unwrap_err();
    assert!(e.to_string().contains("troupe.json"), "{e}");

    let big = bundle_copy();
    let manifest = big.path().join("troupe.json");
    std::fs::File::options()
        .append(true)
        .open(&manifest)
        .unwrap()
        .set_len(LIMITS.max_manifest_bytes + 1)
        .unwrap();
    let e = load_without_hanging(big.path()).unwrap_err();
    assert!(e.to_string().contains("above troupe's limit"), "{e}");
}

#[test]
fn manifest_numbers_beyond_the_limits_are_refused_at_load() {
    type Edit = fn(&mut serde_json::Value);
    let cases: [(&str, Edit); 4] = [
        ("context.layers", |v| {
            v["context"]["layers"] = serde_json::json!((1u64 << 40) + 1)
        }),
        ("vae.encoder.lookahead_frames", |v| {
            v["vae"]["encoder"]["lookahead_frames"] = serde_json::json!(u64::MAX)
        }),
        ("sampler.steps", |v| {
            v["sampler"]["steps"] = serde_json::json!(u32::MAX)
        }),
        ("latent.dim", |v| {
            v["latent"]["dim"] = serde_json::json!(1u64 << 62)
        }),
    ];
    for (field, edit) in cases {
        let dir = bundle_copy();
        edit_manifest(dir.path(), edit);
        let e = Model::load(dir.path()).unwrap_err();
        assert!(matches!(e, Error::Manifest { .. }), "{field}: {e}");
        assert!(e.to_string().contains(field), "{field}: {e}");
    }
    let dir = bundle_copy();
    edit_manifest(dir.path(), |v| {
        v["sampler"]["cfg_scale"] = serde_json::json!(3e38)
    });
    let e = Model::load(dir.path()).unwrap_err();
    assert!(e.to_string().contains("CFG scale"), "{e}");
}

/// `bytes` (an ONNX ModelProto) with one more `opset_import` of the default domain: field 8, a
/// message `{domain: "", version}`. Protobuf appends repeated fields, so the graph now declares
/// that operator set too.
fn with_opset(bytes: &[u8], version: u8) -> Vec<u8> {
    assert!(version < 0x80, "a one-byte varint");
    let mut out = bytes.to_vec();
    out.extend_from_slice(&[0x42, 0x04, 0x0a, 0x00, 0x10, version]);
    out
}

#[test]
fn graphs_of_an_unknown_operator_set_are_refused() {
    let dir = bundle_copy();
    let path = dir.path().join("velocity.onnx");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, with_opset(&bytes, 99)).unwrap();
    // The manifest's digests follow the edit, so that the graph reaches the operator-set check.
    record_digests(dir.path());
    let e = Model::load(dir.path()).unwrap_err();
    assert!(matches!(e, Error::Graph { .. }), "{e}");
    assert!(e.to_string().contains("operator set 99"), "{e}");
}

#[test]
fn sizes_from_the_caller_are_bounded() {
    let m = model();
    let huge_steps = ReactorOptions {
        steps: Some(u32::MAX),
        ..default_options()
    };
    let e = m.session(huge_steps).unwrap_err();
    assert!(matches!(e, Error::InvalidOption(_)), "{e}");
    assert!(e.to_string().contains("limit of 10000"), "{e}");
    let mut s = m.session(default_options()).unwrap();
    assert!(s.set_steps(u32::MAX).is_err());
    let huge_capacity = ReactorOptions {
        context_capacity: Some(usize::MAX),
        ..default_options()
    };
    assert!(m.session(huge_capacity).is_err());

    let lat = m.latent_dim();
    let noise = TokenNoise {
        actor: vec![0.5; lat],
        reactor: vec![0.5; lat],
    };
    let reactor = s.family_mut::<Reactor>().unwrap();
    for _ in 0..LIMITS.max_queued_noise_tokens {
        reactor.queue_noise(noise.clone()).unwrap();
    }
    let e = reactor.queue_noise(noise).unwrap_err();
    assert!(e.to_string().contains("queued noise"), "{e}");
    s.reset();
    let out = s.step(actor().view()).unwrap();
    assert!(out.iter().all(|v| v.is_finite()));
}

#[test]
fn extreme_settings_and_inputs_are_refused_or_give_finite_output_and_the_session_recovers() {
    let m = model();
    let d = m.frame_dim();
    let mut s = m.session(default_options()).unwrap();
    assert!(s.set_cfg_scale(f32::MAX).is_err());
    assert!(s.set_cfg_scale(-f32::MAX).is_err());
    let cfg = ReactorOptions {
        cfg_scale: Some(f32::MAX),
        ..default_options()
    };
    assert!(m.session(cfg).is_err());

    // ±FLT_MAX frames are refused; 200 ordinary frames afterwards are all finite.
    for extreme in [f32::MAX, -f32::MAX, f32::MIN_POSITIVE / 2.0] {
        let frames = Array2::from_elem((4, d), extreme);
        let refused = s.step(frames.view());
        if extreme.abs() > 1.0 {
            assert!(refused.is_err(), "{extreme} refused");
        }
    }
    let actor = actor();
    let rest = run_chunked(&mut s, &actor, 7).0;
    assert!(!rest.is_empty() && rest.iter().all(|v| v.is_finite()));

    // At the limits: every frame out is finite, or the step fails and the session goes on.
    for (cfg, value) in [
        (1000.0, 0.0),
        (-1000.0, 0.0),
        (1.0, 1e6),
        (1.0, -1e6),
        (1.0, -0.0),
    ] {
        let mut s = m
            .session(ReactorOptions {
                cfg_scale: Some(cfg),
                ..default_options()
            })
            .unwrap();
        match s.step(Array2::from_elem((8, d), value).view()) {
            Ok(out) => assert!(
                out.iter().all(|v| v.is_finite()),
                "cfg {cfg}, value {value}"
            ),
            Err(e) => assert!(e.to_string().contains("not finite"), "{e}"),
        }
        s.set_cfg_scale(1.0).unwrap();
        s.reset();
        let out = run_chunked(&mut s, &actor, 5).0;
        assert!(
            out.iter().all(|v| v.is_finite()),
            "after cfg {cfg}, value {value}"
        );
    }
}

#[test]
fn a_long_stream_with_the_smallest_cache_runs() {
    let mut s = model()
        .session(ReactorOptions {
            context_capacity: Some(2),
            ..default_options()
        })
        .unwrap();
    let actor = actor();
    let mut out = 0;
    for _ in 0..3 {
        let (frames, _) = run_chunked(&mut s, &actor, 3);
        assert!(frames.iter().all(|v| v.is_finite()));
        out += frames.len();
        assert_eq!(s.context_len(), 2);
    }
    assert_eq!(out / model().frame_dim(), 3 * actor.nrows() / 4 * 4);
}

#[test]
fn clip_and_text_sizes_are_bounded() {
    let bundle = Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/armflow-tiny-interhuman");
    let m = Model::load(bundle).unwrap();
    let actor = Array2::<f32>::zeros((10, m.frame_dim()));
    let steps = ClipOptions {
        steps: Some(u32::MAX),
        ..Default::default()
    };
    assert!(matches!(
        m.armflow()
            .unwrap()
            .generate_clip(actor.view(), None, &steps),
        Err(Error::InvalidOption(_))
    ));
    let width = m.text_token_dim().expect("a text branch");
    let tokens = Array2::<f32>::zeros((30_000, width));
    let e = m.encode_text(tokens.view(), 0).unwrap_err();
    assert!(e.to_string().contains("limit of 77"), "{e}");
    let tokens = Array2::<f32>::zeros((77, width));
    assert!(m.encode_text(tokens.view(), 76).is_ok());
}

#[test]
fn long_calls_report_progress_and_stop_when_the_callback_says_so() {
    use std::sync::{Arc, Mutex};
    let seen = Arc::new(Mutex::new(Vec::new()));
    let calls = |stop_after: u64| {
        let log = Arc::clone(&seen);
        log.lock().unwrap().clear();
        move |done: u64, total: u64| {
            log.lock().unwrap().push((done, total));
            done < stop_after
        }
    };

    // A load, on one thread and on several.
    for threads in [1, 0] {
        troupe::set_load_threads(threads);
        let e = troupe::with_progress(calls(1), || Model::load(bundle_dir())).unwrap_err();
        assert!(matches!(e, Error::Cancelled(_)), "{e}");
        assert!(e.to_string().contains("loading the bundle"), "{e}");
        assert_eq!(
            seen.lock().unwrap().len(),
            1,
            "the load stopped at the first report"
        );
        let total = seen.lock().unwrap()[0].1;
        let model = troupe::with_progress(calls(u64::MAX), || Model::load(bundle_dir())).unwrap();
        let reports = seen.lock().unwrap().clone();
        assert_eq!(reports.len() as u64, total, "one report per graph");
        assert!(reports
            .iter()
            .enumerate()
            .all(|(i, &(d, t))| d == i as u64 + 1 && t == total));
        drop(model);
    }
    troupe::set_load_threads(0);

    // A group reports every network evaluation: one long solve (10,000 prior steps) stops
    // at the second, long before it would end.
    let umf =
        Model::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/umf-tiny")).unwrap();
    let options = troupe::GroupOptions::default();
    let stages = umf.umf().unwrap().spec().pyramid.stages.len();
    let long = troupe::GroupOptions {
        prior: Some(vec![troupe::Solver::euler(10_000); stages]),
        ..troupe::GroupOptions::default()
    };
    let started = std::time::Instant::now();
    let e = troupe::with_progress(calls(2), || {
        umf.umf().unwrap().generate_group(None, 4, &long)
    })
    .unwrap_err();
    assert!(matches!(e, Error::Cancelled(_)), "{e}");
    let total = 10_000 * stages as u64 + 3 * 4 * 4; // RK4 with 4 steps per further person
    assert_eq!(*seen.lock().unwrap(), [(1, total), (2, total)]);
    assert!(started.elapsed().as_secs_f64() < 5.0);
    assert!(
        umf.umf().unwrap().generate_group(None, 4, &options).is_ok(),
        "no callback outside the scope"
    );

    // A clip stops after its third token.
    let official = Model::load(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/armflow-tiny-interhuman"),
    )
    .unwrap();
    let actor = Array2::<f32>::zeros((20, official.frame_dim()));
    let e = troupe::with_progress(calls(3), || {
        official
            .armflow()
            .unwrap()
            .generate_clip(actor.view(), None, &ClipOptions::default())
    })
    .unwrap_err();
    assert!(e.to_string().contains("the clip was cancelled"), "{e}");
    assert_eq!(seen.lock().unwrap().len(), 3);
}

/// A call budget bounds a long call up front: a group or a clip that would take more work is
/// refused before it starts, and a long solve stops at its time budget; the budget is the
/// calling thread's and ends with its scope.
#[test]
fn long_calls_keep_within_the_threads_call_budget() {
    let umf =
        Model::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/umf-tiny")).unwrap();
    let stages = umf.umf().unwrap().spec().pyramid.stages.len();
    let long = troupe::GroupOptions {
        prior: Some(vec![troupe::Solver::euler(10_000); stages]),
        ..troupe::GroupOptions::default()
    };
    let work = troupe::CallBudget {
        max_work: 1_000,
        max_seconds: 0.0,
    };
    let e = troupe::with_call_budget(work, || umf.umf().unwrap().generate_group(None, 4, &long))
        .unwrap_err();
    let total = 10_000 * stages + 3 * 4 * 4;
    assert!(
        matches!(&e, Error::InvalidOption(m) if m.contains(&format!(
            "the group would take {total} network evaluations, above this thread's call budget of 1000"
        ))),
        "{e}"
    );
    let time = troupe::CallBudget {
        max_work: 0,
        max_seconds: 0.2,
    };
    let started = std::time::Instant::now();
    let e = troupe::with_call_budget(time, || umf.umf().unwrap().generate_group(None, 4, &long))
        .unwrap_err();
    assert!(
        matches!(&e, Error::Cancelled(m) if m.contains("the group stopped at this thread's call budget of 0.2 s")),
        "{e}"
    );
    assert!(started.elapsed().as_secs_f64() < 5.0);
    let options = troupe::GroupOptions::default();
    let roomy = troupe::CallBudget {
        max_work: 100_000,
        max_seconds: 600.0,
    };
    let within = troupe::with_call_budget(roomy, || {
        umf.umf().unwrap().generate_group(None, 2, &options)
    })
    .unwrap();
    let without = umf
        .umf()
        .unwrap()
        .generate_group(None, 2, &options)
        .unwrap();
    assert_eq!(
        within.motion, without.motion,
        "a budget changes nothing it allows"
    );

    // A clip's work is its tokens times its steps.
    let official = Model::load(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/armflow-tiny-interhuman"),
    )
    .unwrap();
    let actor = Array2::<f32>::zeros((20, official.frame_dim()));
    let clip = ClipOptions {
        steps: Some(1_000),
        ..ClipOptions::default()
    };
    let e = troupe::with_call_budget(work, || {
        official
            .armflow()
            .unwrap()
            .generate_clip(actor.view(), None, &clip)
    })
    .unwrap_err();
    assert!(
        e.to_string().contains("the clip would take") && e.to_string().contains("tokens × steps"),
        "{e}"
    );
    for bad in [-1.0, f64::NAN] {
        let bad = troupe::CallBudget {
            max_work: 0,
            max_seconds: bad,
        };
        assert!(troupe::with_call_budget(bad, || Ok(())).is_err());
    }
}

/// A BVH file of a million frames reports every 4096 and stops when told; so does the GIF
/// writer, every frame.
#[test]
fn reading_bvh_and_writing_gifs_can_be_stopped() {
    let mut text = String::from(
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n \
         End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 1000000\nFrame Time: 0.0333\n",
    );
    for _ in 0..1_000_000 {
        text.push_str("0 0 0\n");
    }
    let e = troupe::with_progress(
        |done, total| {
            assert_eq!(
                (done, total),
                (4096, 1_000_000),
                "the first report stops it"
            );
            false
        },
        || troupe::motion::bvh::parse_bvh(text.as_bytes(), "long.bvh"),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("reading the BVH was cancelled"),
        "{e}"
    );

    let mut scene = troupe::viewer::Scene::new(30.0, "").unwrap();
    let pose = ndarray::Array3::<f32>::from_shape_fn((60, 22, 3), |(t, j, d)| {
        (t as f32) * 0.01 + (j as f32) * 0.05 * (d == 1) as u8 as f32
    });
    scene.add_person("p", pose.view()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let gif = dir.path().join("stopped.gif");
    let e = troupe::with_progress(
        |done, _| done < 10,
        || scene.write_gif(&gif, &troupe::viewer::GifOptions::default()),
    )
    .unwrap_err();
    assert!(matches!(e, Error::Cancelled(_)), "{e}");
    assert!(!gif.exists(), "nothing written");
}

/// A latent scale far from 1 (3.4e38, a denormal) made every step overflow after the bundle
/// loaded: it is refused at load, naming the field.
#[test]
fn latent_scales_that_overflow_every_step_are_refused_at_load() {
    for scale in [3.4e38f64, 1e-40, 1e5, 0.0] {
        let dir = common::bundle_copy();
        common::edit_manifest(dir.path(), |m| m["latent"]["scale"] = scale.into());
        let e = Model::load(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("latent.scale must be in [1e-4, 1e4]"),
            "{scale}: {e}"
        );
    }
}

/// A file named by mistake (or by a caller probing a service) is refused without its contents
/// in the message: a service passes its errors on, so a message quoting the file would hand out
/// whatever file a caller names. Each case carries a secret the message must not hold.
#[test]
fn files_that_are_not_bundles_are_refused_without_quoting_them() {
    const SECRET: &str = "root:x:0:0:s3cr3t/hunter2:/root:/bin/bash";
    let dir = tempfile::tempdir().unwrap();
    let mut cases: Vec<(String, std::path::PathBuf)> = Vec::new();
    // Files: the loader tries a single file as a bundle archive.
    let text = dir.path().join("passwd");
    std::fs::write(
        &text,
        format!("{SECRET}\ndaemon:x:1:1::/usr/sbin:/usr/sbin/nologin\n"),
    )
    .unwrap();
    cases.push(("a text file".into(), text));
    let mut binary = SECRET.as_bytes().to_vec();
    binary.extend((0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8));
    let binary_path = dir.path().join("blob");
    std::fs::write(&binary_path, &binary).unwrap();
    cases.push(("a binary file".into(), binary_path));
    // Directories whose manifest is JSON holding the secret where a name or a value belongs.
    let header = r#""format": "troupe-bundle", "format_version": 1, "family": "armflow""#;
    for (what, json) in [
        ("the format", format!(r#"{{"format": "{SECRET}"}}"#)),
        (
            "the family",
            format!(r#"{{"format": "troupe-bundle", "format_version": 1, "family": "{SECRET}"}}"#),
        ),
        (
            "the version",
            format!(r#"{{"format": "troupe-bundle", "format_version": "{SECRET}"}}"#),
        ),
        ("a value", format!(r#"{{{header}, "motion": "{SECRET}"}}"#)),
        ("a key", format!(r#"{{{header}, "{SECRET}": 1}}"#)),
        ("not JSON", SECRET.to_owned()),
    ] {
        let bundle = dir.path().join(what.replace(' ', "-"));
        std::fs::create_dir(&bundle).unwrap();
        std::fs::write(bundle.join("troupe.json"), json).unwrap();
        cases.push((format!("a manifest with the secret as {what}"), bundle));
    }
    for (what, path) in cases {
        let message = load_without_hanging(&path).expect_err(&what).to_string();
        // No run of 6 bytes of the secret (its shortest field is 6) appears.
        for window in SECRET.as_bytes().windows(6) {
            let window = std::str::from_utf8(window).unwrap();
            assert!(
                !message.contains(window),
                "{what}: {message:?} quotes {window:?}"
            );
        }
        assert!(
            message.contains(&path.display().to_string()),
            "{what}: names the file: {message}"
        );
    }
}

/// A graph damaged after export (bits flipped inside the weights, which tract would load) is
/// refused at load, naming the file, because the manifest records every file's SHA-256; so is
/// a manifest whose list leaves a file out or holds no digest. A bundle recording none still
/// loads (with a warning in the log).
#[test]
fn damaged_graphs_are_refused_at_load_by_the_manifests_digests() {
    let graph = "vae_encoder_step.onnx";
    let copy = bundle_copy();
    let path = copy.path().join(graph);
    let mut bytes = std::fs::read(&path).unwrap();
    // Eight flips in the last quarter, where the weights' raw data lie.
    for i in 0..8 {
        let at = bytes.len() - 1 - i * 97;
        bytes[at] ^= 0x10;
    }
    std::fs::write(&path, &bytes).unwrap();
    let e = load_without_hanging(copy.path()).expect_err("a damaged graph is refused");
    assert!(matches!(e, Error::Graph { .. }), "{e:?}");
    let message = e.to_string();
    assert!(
        message.contains(graph) && message.contains("SHA-256"),
        "{message}"
    );

    let manifest_of = |copy: &tempfile::TempDir| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(copy.path().join("troupe.json")).unwrap()).unwrap()
    };
    let write = |copy: &tempfile::TempDir, manifest: &serde_json::Value| {
        std::fs::write(copy.path().join("troupe.json"), manifest.to_string()).unwrap();
    };
    // A file left out of the list.
    let copy = bundle_copy();
    let mut manifest = manifest_of(&copy);
    manifest["sha256"]
        .as_object_mut()
        .unwrap()
        .remove("velocity.onnx");
    write(&copy, &manifest);
    let message = load_without_hanging(copy.path()).err().unwrap().to_string();
    assert!(
        message.contains("velocity.onnx") && message.contains("records no SHA-256"),
        "{message}"
    );
    // A digest that is not one.
    manifest["sha256"]["velocity.onnx"] = "not hex".into();
    write(&copy, &manifest);
    let message = load_without_hanging(copy.path()).err().unwrap().to_string();
    assert!(
        message.contains("sha256 of `velocity.onnx`: not 64 hexadecimal digits"),
        "{message}"
    );
    // No digests at all: an older bundle, loaded as before.
    manifest.as_object_mut().unwrap().remove("sha256");
    write(&copy, &manifest);
    let unchecked = load_without_hanging(copy.path()).expect("loads without digests");
    assert_eq!(unchecked.manifest().sha256.len(), 0);
}
