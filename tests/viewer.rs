//! The viewer as a person sees it: the HTML player rendered by headless Chromium and the GIF
//! decoded, checking that each person's colour appears where their joints project (with the
//! projection written here again from the camera's documented definition), that the actor is on
//! the left and the reactor on the right, and that another frame moves them. Plus the checks
//! on what the scene refuses, atomic writes, the embedded data, and the C entry point.
//! `TROUPE_VIEWER_KEEP=DIR` keeps the screenshots and the GIF in `DIR`, to look at.
//!
//! Chromium is required: the tests fail (never skip) without it. `TROUPE_CHROMIUM` names the
//! binary; otherwise `chromium` (Debian's package, which `.ci/run` installs) is looked up on
//! `PATH`. `TROUPE_BLESS=1` also copies a screenshot to `docs/images/viewer-screenshot.png`.

mod common;

use std::ffi::{c_char, CStr, CString};
use std::path::{Path, PathBuf};
use std::time::Instant;

use ndarray::Array3;
use troupe::motion::{JointsFormat, Skeleton, Units, UpAxis};
use troupe::viewer::{Camera, GifOptions, Scene, MAX_PEOPLE};
use troupe::Error;

use common::pictures::*;

const FRAMES: usize = 30;

// ---------------------------------------------------------------------------------------------
// The scene: an actor in the rest pose at x = -0.8 m lowering its left arm, and a reactor at
// x = +0.8 m turned to face -Z with both arms down, walking 0.6 m toward +Z.

fn rest() -> Vec<[f32; 3]> {
    Skeleton::t2m22()
        .rest_positions()
        .iter()
        .map(|p| p.map(|v| v as f32))
        .collect()
}

/// Rotates every descendant of `joint` about it, by `angle` radians about +Z.
fn swing(pose: &mut [[f32; 3]], joint: usize, angle: f32) {
    let skeleton = Skeleton::t2m22();
    let parents = skeleton.parents();
    let pivot = pose[joint];
    let (s, c) = angle.sin_cos();
    for j in 0..pose.len() {
        let mut a = parents[j];
        let mut below = false;
        while let Some(p) = a {
            if p == joint {
                below = true;
                break;
            }
            a = parents[p];
        }
        if below {
            let [x, y, z] = pose[j];
            let (dx, dy) = (x - pivot[0], y - pivot[1]);
            pose[j] = [pivot[0] + c * dx - s * dy, pivot[1] + s * dx + c * dy, z];
        }
    }
}

fn actor_pose(t: usize) -> Vec<[f32; 3]> {
    let mut pose = rest();
    // Left shoulder (+X side): from the T-pose down by up to 70 degrees.
    swing(
        &mut pose,
        16,
        -(t as f32 / (FRAMES - 1) as f32) * 70f32.to_radians(),
    );
    pose.iter().map(|p| [p[0] - 0.8, p[1], p[2]]).collect()
}

fn reactor_pose(t: usize) -> Vec<[f32; 3]> {
    let mut pose = rest();
    swing(&mut pose, 16, -70f32.to_radians());
    swing(&mut pose, 17, 70f32.to_radians());
    let walked = 0.6 * t as f32 / (FRAMES - 1) as f32;
    // Turned about +Y by 180 degrees, to face -Z.
    pose.iter()
        .map(|p| [0.8 - p[0], p[1], walked - p[2]])
        .collect()
}

fn clip(pose: impl Fn(usize) -> Vec<[f32; 3]>, frames: usize) -> Array3<f32> {
    let flat: Vec<f32> = (0..frames)
        .flat_map(|t| pose(t % FRAMES))
        .flatten()
        .collect();
    Array3::from_shape_vec((frames, 22, 3), flat).unwrap()
}

const TITLE: &str = "actor & reactor";

fn scene() -> Scene {
    titled(TITLE)
}

fn titled(title: &str) -> Scene {
    let mut scene = Scene::new(30.0, title).unwrap();
    scene
        .add_person("actor", clip(actor_pose, FRAMES).view())
        .unwrap();
    scene
        .add_person("reactor", clip(reactor_pose, FRAMES).view())
        .unwrap();
    scene
}

/// Checks both people at frame `t` of `image` seen through `cam`; returns their centroids.
fn check_people(
    what: &str,
    scene: &Scene,
    image: &Image,
    t: usize,
    cam: &Camera,
    radius: i64,
) -> [[f64; 2]; 2] {
    let mut centroids = [[0.0; 2]; 2];
    for (person, colour) in [BLUE, ORANGE].into_iter().enumerate() {
        let joints = projected(scene, person, t, cam, image);
        let seen = see(image, colour, &joints, radius);
        let name = scene.people()[person].name();
        let total = seen.left + seen.right;
        assert!(
            seen.joints_found >= 20,
            "{what}: {name}: only {} of 22 joints have its colour within {radius} px",
            seen.joints_found
        );
        assert!(
            total > 150,
            "{what}: {name}: only {total} pixels of its colour"
        );
        let (ours, theirs) = if person == 0 {
            (seen.left, seen.right)
        } else {
            (seen.right, seen.left)
        };
        assert!(
            ours as f64 >= 0.85 * total as f64,
            "{what}: {name} should be on the {} ({ours} of {total} pixels are)",
            if person == 0 { "left" } else { "right" }
        );
        let _ = theirs;
        assert!(
            (seen.stray as f64) < 0.1 * total as f64,
            "{what}: {name}: {} of {total} pixels of its colour lie away from its bones",
            seen.stray
        );
        centroids[person] = seen.centroid;
    }
    centroids
}

// ---------------------------------------------------------------------------------------------
// The HTML player.

#[test]
fn ui_0_shows_the_people_alone() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let html = dir.path().join("scene.html");
    scene.write_html(&html).unwrap();
    let with = screenshot(&html, "frame=0&paused=1", &dir.path().join("ui.png"));
    let bare = screenshot(&html, "frame=0&paused=1&ui=0", &dir.path().join("bare.png"));
    // The legend (top left) and the bar (bottom) are near-white panels over the grey-beige
    // background: gone with ui=0, and the people are still drawn where their joints project.
    let white = |image: &Image, rows: std::ops::Range<usize>| {
        rows.flat_map(|y| (0..image.width).map(move |x| (x, y)))
            .filter(|&(x, y)| image.rgb[y * image.width + x].iter().all(|&c| c >= 250))
            .count()
    };
    assert!(white(&with, 585..600) > 5000, "the bar is drawn by default");
    assert_eq!(white(&bare, 585..600), 0, "no bar with ui=0");
    assert!(
        white(&with, 15..40) > white(&bare, 15..40) + 500,
        "no legend with ui=0"
    );
    check_people("ui=0", &scene, &bare, 0, &scene.camera(), 4);
}

#[test]
fn the_html_player_shows_each_person_where_their_joints_project() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let html = dir.path().join("scene.html");
    scene.write_html(&html).unwrap();
    if let Some(keep) = std::env::var_os("TROUPE_VIEWER_KEEP") {
        let _ = std::fs::copy(&html, Path::new(&keep).join("scene.html"));
    }
    let cam = scene.camera();
    let first = screenshot(&html, "frame=0&paused=1", &dir.path().join("0.png"));
    assert_eq!((first.width, first.height), (800, 600));
    let last = screenshot(&html, "frame=29&paused=1", &dir.path().join("29.png"));
    let a = check_people("frame 0", &scene, &first, 0, &cam, 4);
    let b = check_people("frame 29", &scene, &last, 29, &cam, 4);
    // The reactor walked: its pixels moved as its projected joints did.
    let mean = |v: &[[f64; 2]]| {
        let n = v.len() as f64;
        [
            v.iter().map(|p| p[0]).sum::<f64>() / n,
            v.iter().map(|p| p[1]).sum::<f64>() / n,
        ]
    };
    let p0 = mean(&projected(&scene, 1, 0, &cam, &first));
    let p1 = mean(&projected(&scene, 1, 29, &cam, &last));
    let want = [p1[0] - p0[0], p1[1] - p0[1]];
    let got = [b[1][0] - a[1][0], b[1][1] - a[1][1]];
    let length = (want[0] * want[0] + want[1] * want[1]).sqrt();
    assert!(length > 10.0, "the reactor should move on screen: {want:?}");
    let error = ((got[0] - want[0]).powi(2) + (got[1] - want[1]).powi(2)).sqrt();
    assert!(
        error < 0.25 * length + 3.0,
        "the reactor's pixels moved by {got:?}, its joints by {want:?}"
    );
    // And the frames differ where the actor lowered its arm.
    let changed = first
        .rgb
        .iter()
        .zip(&last.rgb)
        .filter(|(x, y)| close(**x, BLUE) != close(**y, BLUE))
        .count();
    assert!(
        changed > 100,
        "the actor's pixels barely changed ({changed})"
    );
    if std::env::var_os("TROUPE_BLESS").is_some() {
        let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/images");
        std::fs::create_dir_all(&docs).unwrap();
        std::fs::copy(
            dir.path().join("29.png"),
            docs.join("viewer-screenshot.png"),
        )
        .unwrap();
    }
}

#[test]
fn the_player_takes_its_camera_from_the_query() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let html = dir.path().join("scene.html");
    scene.write_html(&html).unwrap();
    let cam = Camera {
        yaw_deg: -35.0,
        pitch_deg: 25.0,
        distance: 5.5,
        ..scene.camera()
    };
    let image = screenshot(
        &html,
        "frame=15&paused=1&yaw=-35&pitch=25&distance=5.5",
        &dir.path().join("15.png"),
    );
    check_people(
        "frame 15, camera from the query",
        &scene,
        &image,
        15,
        &cam,
        4,
    );
    // The library's own projection agrees with the one written here.
    for p in [[0.3f32, 1.2, -0.4], [-1.0, 0.0, 0.5]] {
        let ours = project(&cam, p, 800.0, 600.0).unwrap();
        let theirs = cam.project(p, 800.0, 600.0).unwrap();
        assert!(
            (ours[0] - f64::from(theirs[0])).abs() < 0.01,
            "{ours:?} {theirs:?}"
        );
        assert!(
            (ours[1] - f64::from(theirs[1])).abs() < 0.01,
            "{ours:?} {theirs:?}"
        );
    }
}

/// The data element of a player page, parsed.
fn embedded(html: &str) -> serde_json::Value {
    let open = "<script type=\"application/json\" id=\"troupe-data\">";
    let start = html.find(open).expect("the data element") + open.len();
    let end = start + html[start..].find("</script>").unwrap();
    serde_json::from_str(&html[start..end]).unwrap()
}

#[test]
fn the_page_is_self_contained_and_its_data_is_inert_and_rounded() {
    let mut scene = titled("actor & reactor </script>");
    let evil = "</script><script>alert(1)</script><!--";
    scene
        .add_person(evil, clip(actor_pose, 3).view())
        .unwrap()
        .set_colour([10, 20, 30]);
    let html = scene.to_html().unwrap();
    let lower = html.to_lowercase();
    for network in [
        "http:",
        "https:",
        "//cdn",
        "src=",
        "<link",
        "@import",
        "url(",
        "@font-face",
    ] {
        assert!(!lower.contains(network), "the page mentions {network:?}");
    }
    // Only the page's own two script elements close.
    assert_eq!(lower.matches("</script").count(), 2);
    assert_eq!(lower.matches("<script").count(), 2);
    assert!(html.contains("<title>actor &amp; reactor &lt;/script&gt; · troupe</title>"));
    let data = embedded(&html);
    assert_eq!(data["title"], "actor & reactor </script>");
    assert_eq!(data["frames"], FRAMES);
    assert_eq!(data["people"][2]["name"], evil);
    assert_eq!(data["people"][2]["frames"], 3);
    assert_eq!(data["people"][0]["colour"], "#1f77b4");
    assert_eq!(data["people"][1]["colour"], "#ff7f0e");
    assert_eq!(data["people"][2]["colour"], "#0a141e");
    assert_eq!(data["parents"][0], -1);
    assert_eq!(data["parents"][21], 19);
    let unit = data["unit"].as_f64().unwrap();
    assert_eq!(unit, 1e-4);
    let positions = data["people"][1]["positions"].as_array().unwrap();
    assert_eq!(positions.len(), FRAMES * 66);
    let original = scene.people()[1].positions();
    for (value, want) in positions.iter().zip(original.iter()) {
        let got = value.as_i64().unwrap() as f64 * unit;
        assert!(
            (got - f64::from(*want)).abs() <= 0.5e-4 + 1e-7,
            "{got} vs {want}"
        );
    }
    let cam = scene.camera();
    let number = |v: &serde_json::Value| v.as_f64().unwrap() as f32;
    assert_eq!(number(&data["camera"]["yaw"]), cam.yaw_deg);
    assert_eq!(number(&data["camera"]["distance"]), cam.distance);
}

// ---------------------------------------------------------------------------------------------
// The GIF.

struct Gif {
    width: usize,
    height: usize,
    frames: Vec<Image>,
    delays_cs: Vec<u16>,
}

fn decode_gif(bytes: &[u8]) -> Gif {
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options.read_info(bytes).unwrap();
    let (width, height) = (decoder.width() as usize, decoder.height() as usize);
    let mut canvas = vec![[0u8; 3]; width * height];
    let (mut frames, mut delays_cs) = (Vec::new(), Vec::new());
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        let (left, top) = (frame.left as usize, frame.top as usize);
        for y in 0..frame.height as usize {
            for x in 0..frame.width as usize {
                let p = &frame.buffer[4 * (y * frame.width as usize + x)..][..4];
                if p[3] != 0 {
                    canvas[(top + y) * width + left + x] = [p[0], p[1], p[2]];
                }
            }
        }
        delays_cs.push(frame.delay);
        frames.push(Image {
            width,
            height,
            rgb: canvas.clone(),
        });
    }
    Gif {
        width,
        height,
        frames,
        delays_cs,
    }
}

#[test]
fn the_gif_shows_both_people_moving_where_they_project() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.gif");
    let options = GifOptions::default();
    scene.write_gif(&path, &options).unwrap();
    if let Some(keep) = std::env::var_os("TROUPE_VIEWER_KEEP") {
        let _ = std::fs::copy(&path, Path::new(&keep).join("scene.gif"));
    }
    let gif = decode_gif(&std::fs::read(&path).unwrap());
    assert_eq!((gif.width, gif.height), (480, 360));
    let stride = options.stride(30.0);
    assert_eq!(stride, 2);
    assert_eq!(gif.frames.len(), FRAMES.div_ceil(stride));
    let total: u32 = gif.delays_cs.iter().map(|&d| u32::from(d)).sum();
    assert_eq!(total, 100, "a 1 s clip lasts {total} cs");
    let cam = scene.camera();
    let first = check_people("GIF frame 0", &scene, &gif.frames[0], 0, &cam, 3);
    let n = gif.frames.len() - 1;
    let last = check_people(
        &format!("GIF frame {n}"),
        &scene,
        &gif.frames[n],
        n * stride,
        &cam,
        3,
    );
    let moved = (last[1][0] - first[1][0]).hypot(last[1][1] - first[1][1]);
    assert!(moved > 5.0, "the reactor moved {moved} px in the GIF");
    // A custom size and camera.
    let small = GifOptions {
        width: 240,
        height: 320,
        max_fps: 30.0,
        camera: Some(Camera {
            yaw_deg: 0.0,
            ..cam
        }),
        repeat: false,
    };
    let gif = decode_gif(&scene.to_gif(&small).unwrap());
    assert_eq!(
        (gif.width, gif.height, gif.frames.len()),
        (240, 320, FRAMES)
    );
    check_people(
        "small GIF",
        &scene,
        &gif.frames[7],
        7,
        &small.camera.unwrap(),
        3,
    );
}

#[test]
fn a_ten_second_clip_stays_small() {
    // Both people keep moving for 10 s: the actor circles, the reactor paces left and right,
    // both swinging their arms, so that every frame of the GIF changes.
    let frames = 300;
    let moving = |person: usize| {
        let flat: Vec<f32> = (0..frames)
            .flat_map(|t| {
                let phase = t as f32 / 30.0;
                let mut pose = rest();
                swing(&mut pose, 16, -1.2 + 0.5 * (3.0 * phase).sin());
                swing(&mut pose, 17, 1.2 + 0.5 * (3.0 * phase).cos());
                let (dx, dz) = if person == 0 {
                    (-0.8 + 0.5 * phase.cos(), 0.5 * phase.sin())
                } else {
                    (0.8 + 0.4 * (0.7 * phase).sin(), 0.0)
                };
                pose.into_iter().map(move |p| [p[0] + dx, p[1], p[2] + dz])
            })
            .flatten()
            .collect();
        Array3::from_shape_vec((frames, 22, 3), flat).unwrap()
    };
    let mut scene = Scene::new(30.0, "ten seconds").unwrap();
    scene.add_person("actor", moving(0).view()).unwrap();
    scene.add_person("reactor", moving(1).view()).unwrap();
    let start = Instant::now();
    let html = scene.to_html().unwrap();
    let html_time = start.elapsed();
    let start = Instant::now();
    let gif = scene.to_gif(&GifOptions::default()).unwrap();
    let gif_time = start.elapsed();
    println!(
        "10 s, 2 people, 30 fps: HTML {} bytes ({html_time:?}), GIF {} bytes, {} frames \
         ({gif_time:?})",
        html.len(),
        gif.len(),
        decode_gif(&gif).frames.len()
    );
    assert!(html.len() < 1_000_000, "HTML of {} bytes", html.len());
    assert!(gif.len() < 2_000_000, "GIF of {} bytes", gif.len());
}

// ---------------------------------------------------------------------------------------------
// What the scene refuses, and writes that leave nothing behind.

fn invalid(result: Result<impl std::fmt::Debug, Error>, needle: &str) {
    match result {
        Err(Error::InvalidInput(m)) | Err(Error::InvalidOption(m)) => {
            assert!(m.contains(needle), "{m:?} should mention {needle:?}")
        }
        other => panic!("expected an invalid input naming {needle:?}, got {other:?}"),
    }
}

#[test]
fn bad_scenes_are_refused_with_the_reason() {
    let good = clip(actor_pose, 2);
    let mut scene = Scene::new(30.0, "").unwrap();
    let mut nan = good.clone();
    nan[[1, 20, 1]] = f32::NAN;
    invalid(
        scene.add_person("a", nan.view()).map(|_| ()),
        "frame 1, joint 20 (left_wrist)",
    );
    let mut far = good.clone();
    far[[0, 0, 0]] = 1e6;
    invalid(
        scene.add_person("a", far.view()).map(|_| ()),
        "farther than",
    );
    invalid(
        scene
            .add_person("a", Array3::zeros((2, 21, 3)).view())
            .map(|_| ()),
        "[2, 21, 3]",
    );
    invalid(
        scene
            .add_person("a", Array3::zeros((0, 22, 3)).view())
            .map(|_| ()),
        "0 frames",
    );
    invalid(scene.add_person("", good.view()).map(|_| ()), "name");
    invalid(
        scene.add_person("x".repeat(65), good.view()).map(|_| ()),
        "65 characters",
    );
    invalid(Scene::new(0.0, ""), "frame rate");
    invalid(Scene::new(f32::NAN, ""), "frame rate");
    invalid(Scene::new(30.0, "t".repeat(201)), "title");
    invalid(scene.to_html(), "no people");
    invalid(scene.to_gif(&GifOptions::default()), "no people");
    for _ in 0..MAX_PEOPLE {
        scene.add_person("p", good.view()).unwrap();
    }
    invalid(
        scene.add_person("one more", good.view()).map(|_| ()),
        "at most 8",
    );
    for options in [
        GifOptions {
            width: 8,
            ..Default::default()
        },
        GifOptions {
            max_fps: 0.0,
            ..Default::default()
        },
        GifOptions {
            camera: Some(Camera {
                distance: f32::NAN,
                ..scene.camera()
            }),
            ..Default::default()
        },
    ] {
        match scene.to_gif(&options) {
            Err(Error::InvalidOption(_)) => {}
            other => panic!("{options:?}: {other:?}"),
        }
    }
}

#[test]
fn failed_writes_leave_nothing_behind() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no/such/dir/scene.html");
    match scene.write_html(&missing) {
        Err(Error::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("{other:?}"),
    }
    // The target is a directory: refused before anything is written (the writers' policy,
    // `src/shared/files.rs`).
    let taken = dir.path().join("taken.gif");
    std::fs::create_dir(&taken).unwrap();
    match scene.write_gif(&taken, &GifOptions::default()) {
        Err(Error::InvalidInput(m)) => assert!(m.contains("a directory"), "{m}"),
        other => panic!("{other:?}"),
    }
    let empty = Scene::new(30.0, "").unwrap();
    assert!(empty.write_html(dir.path().join("empty.html")).is_err());
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, vec![std::ffi::OsString::from("taken.gif")]);
    // A good write replaces the file whole.
    let html = dir.path().join("scene.html");
    std::fs::write(&html, "old").unwrap();
    scene.write_html(&html).unwrap();
    assert_eq!(
        std::fs::read_to_string(&html).unwrap(),
        scene.to_html().unwrap()
    );
}

#[test]
fn positions_in_the_callers_world_are_converted() {
    let format = JointsFormat {
        units: Units::Centimeters,
        up: UpAxis::Z,
        fps: 20.0,
        ..Default::default()
    };
    let canonical = clip(reactor_pose, 4);
    // Canonical (x, y, z) is Z-up (x, -z, y); in centimetres.
    let world = Array3::from_shape_fn((4, 22, 3), |(t, j, d)| {
        100.0
            * match d {
                0 => canonical[[t, j, 0]],
                1 => -canonical[[t, j, 2]],
                _ => canonical[[t, j, 1]],
            }
    });
    let scene = Scene::from_world("z up", &format, &[("reactor", world.view())]).unwrap();
    assert_eq!(scene.fps(), 20.0);
    let got = scene.people()[0].positions();
    for (a, b) in got.iter().zip(canonical.iter()) {
        assert!((a - b).abs() < 1e-5, "{a} vs {b}");
    }
}

// ---------------------------------------------------------------------------------------------
// The C entry point, called from Rust.

#[test]
fn the_c_entry_point_writes_both_pictures_or_nothing() {
    use troupe::ffi::motion::{troupe_joints_format, troupe_joints_format_init};
    use troupe::ffi::status::{
        TROUPE_ERR_INVALID_ARG, TROUPE_ERR_IO, TROUPE_ERR_NULL_ARG, TROUPE_OK,
    };
    use troupe::ffi::viewer::troupe_viewer_write;

    let dir = tempfile::tempdir().unwrap();
    let c = |p: PathBuf| CString::new(p.to_str().unwrap()).unwrap();
    let (html, gif) = (c(dir.path().join("c.html")), c(dir.path().join("c.gif")));
    let mut format = std::mem::MaybeUninit::<troupe_joints_format>::uninit();
    let size = std::mem::size_of::<troupe_joints_format>();
    // SAFETY: writable for its size.
    assert_eq!(
        unsafe { troupe_joints_format_init(format.as_mut_ptr(), size) },
        TROUPE_OK
    );
    // SAFETY: initialised above.
    let format = unsafe { format.assume_init() };
    let people: Vec<f32> = clip(actor_pose, FRAMES)
        .iter()
        .chain(clip(reactor_pose, FRAMES).iter())
        .copied()
        .collect();
    let names = [
        CString::new("actor").unwrap(),
        CString::new("reactor").unwrap(),
    ];
    let name_ptrs = [names[0].as_ptr(), names[1].as_ptr()];
    let title = CString::new(TITLE).unwrap();
    let call = |html: *const c_char, gif: *const c_char, positions: &[f32], n_people: usize| {
        // SAFETY: valid strings, positions of n_people * FRAMES * 66 floats, a valid format.
        unsafe {
            troupe_viewer_write(
                html,
                gif,
                positions.as_ptr(),
                n_people,
                FRAMES,
                &format,
                name_ptrs.as_ptr(),
                title.as_ptr(),
            )
        }
    };
    assert_eq!(call(html.as_ptr(), gif.as_ptr(), &people, 2), TROUPE_OK);
    // The same pictures as the Rust API draws.
    let scene = scene();
    let written = std::fs::read_to_string(dir.path().join("c.html")).unwrap();
    assert_eq!(written, scene.to_html().unwrap());
    assert_eq!(
        std::fs::read(dir.path().join("c.gif")).unwrap(),
        scene.to_gif(&GifOptions::default()).unwrap()
    );
    assert_eq!(
        call(std::ptr::null(), std::ptr::null(), &people, 2),
        TROUPE_ERR_NULL_ARG
    );
    let mut bad = people.clone();
    bad[FRAMES * 66 + 5] = f32::INFINITY;
    let (h2, g2) = (c(dir.path().join("d.html")), c(dir.path().join("d.gif")));
    assert_eq!(
        call(h2.as_ptr(), g2.as_ptr(), &bad, 2),
        TROUPE_ERR_INVALID_ARG
    );
    // SAFETY: NULL or a NUL-terminated string valid until the next call on this thread.
    let message = unsafe { CStr::from_ptr(troupe::ffi::status::troupe_last_error_message()) }
        .to_string_lossy()
        .into_owned();
    assert!(message.contains("reactor: frame 0, joint 1"), "{message}");
    assert_eq!(
        call(h2.as_ptr(), g2.as_ptr(), &people, 0),
        TROUPE_ERR_INVALID_ARG
    );
    let missing = c(dir.path().join("missing/d.gif"));
    assert_eq!(
        call(h2.as_ptr(), missing.as_ptr(), &people, 2),
        TROUPE_ERR_IO
    );
    // Nothing of the failed calls was written, not even the HTML of the last one.
    let mut left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["c.gif", "c.html"]);
}

// ---------------------------------------------------------------------------------------------
// MAGNet's SMPL-X frames, posed on the t2m-22 skeleton.

/// The live partner's golden stream and its user, posed and played: each person's colour lies
/// on its projected bones at the first and the last frame, and the partner moved.
#[test]
fn magnet_frames_posed_on_the_skeleton_show_where_their_joints_project() {
    use ndarray::Array2;
    use ndarray_npy::read_npy;
    use troupe::motion::smplx145_positions;

    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/magnet-tiny/golden");
    let clip: Array3<f32> = read_npy(golden.join("frames.npy")).unwrap();
    let partner: Array2<f32> = read_npy(golden.join("live_stream_frames.npy")).unwrap();
    let n = partner.nrows();
    let user = clip
        .slice(ndarray::s![..n, 0, ..])
        .as_standard_layout()
        .into_owned();
    let skeleton = Skeleton::t2m22();
    let pose = |frames: &[f32]| {
        let joints = smplx145_positions(frames, &skeleton).unwrap();
        let flat: Vec<f32> = joints
            .iter()
            .flatten()
            .flatten()
            .map(|v| *v as f32)
            .collect();
        Array3::from_shape_vec((joints.len(), 22, 3), flat).unwrap()
    };
    let mut scene = Scene::new(30.0, "MAGNet live partner").unwrap();
    scene
        .add_person("user", pose(user.as_slice().unwrap()).view())
        .unwrap();
    scene
        .add_person("partner", pose(partner.as_slice().unwrap()).view())
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let html = dir.path().join("magnet.html");
    scene.write_html(&html).unwrap();
    let cam = scene.camera();
    let last = n - 1;
    let mut centroids = Vec::new();
    for t in [0, last] {
        let image = screenshot(
            &html,
            &format!("frame={t}&paused=1"),
            &dir.path().join(format!("{t}.png")),
        );
        if let Some(keep) = std::env::var_os("TROUPE_VIEWER_KEEP") {
            let _ = std::fs::copy(
                dir.path().join(format!("{t}.png")),
                Path::new(&keep).join(format!("magnet-{t}.png")),
            );
        }
        for (person, colour) in [BLUE, ORANGE].into_iter().enumerate() {
            let joints = projected(&scene, person, t, &cam, &image);
            let seen = see(&image, colour, &joints, 4);
            let total = seen.left + seen.right;
            assert!(
                seen.joints_found >= 18,
                "frame {t}, person {person}: {} of 22 joints have its colour",
                seen.joints_found
            );
            assert!(total > 80, "frame {t}, person {person}: {total} pixels");
            // The legend's dot of the person's colour (about 60 pixels) counts as stray.
            assert!(
                (seen.stray as f64) < 0.1 * total as f64 + 80.0,
                "frame {t}, person {person}: {} of {total} pixels away from its bones",
                seen.stray
            );
            centroids.push(seen.centroid);
        }
    }
    let moved = ((centroids[3][0] - centroids[1][0]).powi(2)
        + (centroids[3][1] - centroids[1][1]).powi(2))
    .sqrt();
    assert!(
        moved > 3.0,
        "the partner's pixels barely moved ({moved:.1} px)"
    );
}
