//! The motion layer on real motion capture: 8 s of a CMU subject (`tests/data/mocap/`, see its
//! PROVENANCE.md) through `encode_clip`, against the features of an independent numpy
//! transcription of InterGen's `process_motion_np` (`onnx/troupe_onnx/motion/intergen.py`, with
//! the inverse kinematics of `onnx/troupe_onnx/motion/ik.py`), and back through `decode_frame`
//! and forward kinematics.

use std::path::PathBuf;

use ndarray::{Array2, Array3, Axis};
use ndarray_npy::read_npy;
use troupe::motion::ik::{forward_kinematics, inverse_kinematics};
use troupe::motion::vec3::{norm, sub, Vec3};
use troupe::motion::{
    decode_frame, encode_clip, Handedness, JointsFormat, Skeleton, Units, UpAxis, FEATURE_DIM,
};

/// The clip's rate (CMU captures at 120 fps) and the bundles' (InterHuman's 30 fps).
const CLIP_FPS: f32 = 120.0;
const FEATURE_FPS: f32 = 30.0;
const STRIDE: usize = 4;

/// Largest difference allowed between troupe and the numpy transcription, per value.
const PARITY_TOL: f32 = 1e-5;
/// Largest position error of positions -> features -> `decode_frame`, metres.
const ROUND_TRIP_TOL: f32 = 1e-5;

fn mocap(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/mocap")
        .join(name)
}

/// `[960, 22, 3]` t2m-22 joint positions, metres, z up, 120 fps.
fn clip() -> Array3<f32> {
    read_npy(mocap("cmu-playground-120fps.npy")).expect("the committed CMU excerpt")
}

/// `[239, 262]`: the transcription's features of every 4th frame of the clip.
fn golden() -> Array2<f32> {
    read_npy(mocap("cmu-playground.features.npy")).expect("the committed golden features")
}

fn format() -> JointsFormat {
    JointsFormat {
        units: Units::Meters,
        up: UpAxis::Z,
        handedness: Handedness::Right,
        fps: CLIP_FPS,
    }
}

#[test]
fn cmu_features_equal_the_intergen_transcription() {
    let (clip, golden) = (clip(), golden());
    assert_eq!(clip.shape(), [960, 22, 3]);
    let encoded = encode_clip(clip.view(), format(), FEATURE_FPS, None).unwrap();
    assert_eq!(encoded.features.shape(), [239, FEATURE_DIM]);
    assert_eq!(golden.shape(), encoded.features.shape());
    let slices = [
        ("positions", 0..66),
        ("velocities", 66..132),
        ("rotations", 132..258),
        ("contacts", 258..262),
    ];
    let mut failures = Vec::new();
    for (name, cols) in slices {
        let (mut worst, mut at) = (0f32, (0, cols.start));
        for (t, (ours, theirs)) in encoded
            .features
            .outer_iter()
            .zip(golden.outer_iter())
            .enumerate()
        {
            for c in cols.clone() {
                let d = (ours[c] - theirs[c]).abs();
                if d > worst || d.is_nan() {
                    (worst, at) = (d, (t, c));
                }
            }
        }
        let (t, c) = at;
        println!(
            "{name:10}: max |troupe - transcription| = {worst:.3e} (frame {t}, column {c}: {} vs {})",
            encoded.features[[t, c]],
            golden[[t, c]]
        );
        if worst > PARITY_TOL || worst.is_nan() {
            failures.push(format!("{name}: {worst} at frame {t}, column {c}"));
        }
    }
    assert!(
        failures.is_empty(),
        "troupe differs from the transcription by more than {PARITY_TOL}: {failures:?}"
    );
    let contacts = golden.slice(ndarray::s![.., 258..]).sum();
    println!(
        "contact values set in the golden: {contacts} of {}",
        4 * golden.nrows()
    );
}

#[test]
fn cmu_positions_come_back_through_features_and_decode_frame() {
    let clip = clip();
    let encoded = encode_clip(clip.view(), format(), FEATURE_FPS, None).unwrap();
    let mut worst = 0f32;
    for (t, row) in encoded.features.outer_iter().enumerate() {
        let pose = decode_frame(row, &encoded.placement).unwrap();
        let input = clip.index_axis(Axis(0), STRIDE * t);
        for j in 0..22 {
            for d in 0..3 {
                worst = worst.max((pose.positions[j][d] - input[[j, d]]).abs());
            }
        }
    }
    println!("positions -> features -> decode_frame: max error {worst:.3e} m");
    assert!(worst <= ROUND_TRIP_TOL, "worst position error {worst} m");
}

#[test]
fn cmu_inverse_then_forward_kinematics_with_a_fitted_skeleton() {
    let clip = clip();
    let encoded = encode_clip(clip.view(), format(), FEATURE_FPS, None).unwrap();
    // Every 120 fps frame in the clip's canonical frame.
    let canonical: Vec<Vec<Vec3>> = clip
        .outer_iter()
        .map(|frame| {
            frame
                .outer_iter()
                .map(|p| encoded.placement.world_to_frame([p[0], p[1], p[2]]))
                .collect()
        })
        .collect();
    let neutral = Skeleton::t2m22();
    let fitted = neutral.fitted_to(&canonical);
    let mut max = [0f64; 22];
    let mut sum = [0f64; 22];
    for pose in &canonical {
        let rotations = inverse_kinematics(&neutral, pose);
        let again = forward_kinematics(&fitted, pose[0], &rotations);
        for j in 0..22 {
            let e = norm(sub(pose[j], again[j]));
            max[j] = max[j].max(e);
            sum[j] += e;
        }
    }
    println!(
        "IK -> FK residual per joint over {} frames:",
        canonical.len()
    );
    for (j, name) in neutral.names().iter().enumerate() {
        println!(
            "  {name:15} max {:6.2} mm, mean {:6.2} mm",
            max[j] * 1e3,
            sum[j] / canonical.len() as f64 * 1e3
        );
    }
    // Measured on this clip (the numpy IK of onnx/troupe_onnx/motion/ik.py gives the same), max
    // per joint: 0 at the pelvis; 31.2 mm on the hips and legs and 13.7 mm on spine1..3 (the
    // pelvis branch); 52.3 mm on neck and head and 18.7 mm on the collars and arms (the spine3
    // branch). CMU's lowerback bends between the root, which carries the hips, and spine1, and the
    // clavicles and lowerneck move against the thorax, so the pelvis and spine3 branch triangles
    // are not rigid: their frames tilt with the bend and the fitted (mean) shape misses by up to
    // a few centimetres; single-child bones are rigid, so each chain carries its branch's error
    // unchanged. The bounds sit a little above the measurement.
    let bound_mm = |j: usize| match j {
        0 => 1e-6,
        12 | 15 => 55.0,           // neck, head: the spine3 branch and its child
        3 | 6 | 9 => 15.0,         // spine1, spine2, spine3: the pelvis branch's up child
        13 | 14 | 16..=21 => 20.0, // collars and arms: the spine3 branch
        _ => 33.0,                 // hips and legs: the pelvis branch
    };
    for (j, name) in neutral.names().iter().enumerate() {
        assert!(
            max[j] * 1e3 <= bound_mm(j),
            "{name}: residual {:.2} mm above {} mm",
            max[j] * 1e3,
            bound_mm(j)
        );
    }
}

/// Finite in, finite out, or an error: a placement or a joint position beyond 1e6 m (a floor
/// of 1e300 gave non-finite features before) is refused by the clip encoder and the feature
/// stream, naming what; a stream left as it was by a refused reset.
#[test]
fn placements_and_positions_beyond_the_world_are_refused() {
    use troupe::motion::stream::FeatureStream;
    use troupe::motion::Placement;
    let clip = clip().slice(ndarray::s![..20, .., ..]).to_owned();
    let far = |floor: f64| Placement {
        floor,
        ..Placement::identity(format())
    };
    for floor in [1e300, -1e300, 2e6] {
        let err = encode_clip(clip.view(), format(), FEATURE_FPS, Some(&far(floor)))
            .unwrap_err()
            .to_string();
        assert!(err.contains("placement"), "{err}");
        let err = FeatureStream::new(format(), FEATURE_FPS, Some(far(floor)))
            .unwrap_err()
            .to_string();
        assert!(err.contains("within 1000000 m"), "{err}");
    }
    let near = encode_clip(clip.view(), format(), FEATURE_FPS, Some(&far(-1e5))).unwrap();
    assert!(near.features.iter().all(|v| v.is_finite()));
    let mut huge = clip.clone();
    huge[[3, 5, 0]] = 3e30;
    let err = encode_clip(huge.view(), format(), FEATURE_FPS, None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("frame 3, joint 5") && err.contains("beyond"),
        "{err}"
    );
    let mut stream = FeatureStream::new(format(), FEATURE_FPS, None).unwrap();
    assert!(stream.reset(Some(far(f64::INFINITY))).is_err());
    assert!(stream.reset(None).is_ok());
}
