//! End-to-end checks of the motion layer: a moving body through features and back.

use ndarray::{Array3, Axis};

use super::ik::forward_kinematics;
use super::rotation::Quat;
use super::vec3::normalize;
use super::*;

/// Two seconds of the neutral body walking-ish along a curve, in a z-up centimetre world.
fn walking_clip(frames: usize, format: &JointsFormat) -> Array3<f32> {
    let skeleton = Skeleton::t2m22();
    let mut out = Array3::<f32>::zeros((frames, 22, 3));
    for t in 0..frames {
        let s = t as f64 / 30.0;
        let local: Vec<Quat> = (0..22)
            .map(|j| {
                let a = 2.0 * s + j as f64;
                let axis = normalize([1.0, 0.3 * a.sin(), 0.2 * a.cos()]).unwrap();
                if j == 0 {
                    Quat::from_axis_angle([0.0, 1.0, 0.0], 0.4 * s + 2.0)
                } else {
                    Quat::from_axis_angle(axis, 0.4 * (3.0 * s + j as f64).sin())
                }
            })
            .collect();
        let root = [1.5 + 0.8 * s, 0.95 + 0.02 * (6.0 * s).sin(), -2.0 + 0.3 * s];
        let canonical = forward_kinematics(&skeleton, root, &local);
        for (j, p) in canonical.iter().enumerate() {
            let w = format.from_canonical_axes(*p);
            for d in 0..3 {
                out[[t, j, d]] = w[d];
            }
        }
    }
    out
}

fn z_up_cm() -> JointsFormat {
    JointsFormat {
        units: Units::Centimeters,
        up: UpAxis::Z,
        ..Default::default()
    }
}

#[test]
fn positions_features_positions_round_trip_in_the_callers_world() {
    let format = z_up_cm();
    let clip = walking_clip(60, &format);
    let encoded = encode_clip(clip.view(), format, 30.0, None).unwrap();
    assert_eq!(encoded.features.shape(), [59, 262]);
    let mut worst = 0f32;
    for (t, row) in encoded.features.outer_iter().enumerate() {
        let pose = decode_frame(row, &encoded.placement).unwrap();
        for j in 0..22 {
            for d in 0..3 {
                // Centimetres in, centimetres out; 1e-5 m is 1e-3 cm.
                worst = worst.max((pose.positions[j][d] - clip[[t, j, d]]).abs() / 100.0);
            }
        }
    }
    assert!(worst < 1e-5, "worst position error {worst} m");
}

#[test]
fn the_canonical_frame_is_intergens() {
    let format = z_up_cm();
    let encoded = encode_clip(walking_clip(40, &format).view(), format, 30.0, None).unwrap();
    let f = &encoded.features;
    let lowest = f
        .outer_iter()
        .flat_map(|r| (0..22).map(move |j| r[3 * j + 1]))
        .fold(f32::INFINITY, f32::min);
    assert!(lowest.abs() < 1e-6, "lowest joint at {lowest}");
    assert!(
        f[[0, 0]].abs() < 1e-6 && f[[0, 2]].abs() < 1e-6,
        "root xz at the origin"
    );
    // Facing +Z: right hip - left hip points to -X.
    let across = [f[[0, 6]] - f[[0, 3]], f[[0, 8]] - f[[0, 5]]];
    assert!(across[0] < 0.0 && across[1].abs() < 1e-5, "{across:?}");
}

#[test]
fn feature_rotations_reproduce_the_pose_through_forward_kinematics() {
    let format = JointsFormat::default();
    let clip = walking_clip(30, &format);
    let encoded = encode_clip(clip.view(), format, 30.0, None).unwrap();
    let skeleton = Skeleton::t2m22();
    for row in encoded.features.outer_iter() {
        let pose = decode_frame(row, &encoded.placement).unwrap();
        let local: Vec<Quat> = pose
            .rotations
            .iter()
            .map(|q| Quat::from_wxyz(q.map(f64::from)))
            .collect();
        let root = pose.positions[0].map(f64::from);
        let again = forward_kinematics(&skeleton, root, &local);
        for (a, b) in pose.positions.iter().zip(&again) {
            for d in 0..3 {
                assert!((f64::from(a[d]) - b[d]).abs() < 1e-5, "{a:?} vs {b:?}");
            }
        }
    }
}

#[test]
fn a_stream_gives_the_batch_features_one_frame_late() {
    let format = z_up_cm();
    let clip = walking_clip(50, &format);
    let mut stream = FeatureStream::new(format, 30.0, None).unwrap();
    let mut rows = Vec::new();
    for (t, frame) in clip.outer_iter().enumerate() {
        let out = stream.push(frame).unwrap();
        assert_eq!(out.len(), usize::from(t > 0), "frame {t}");
        rows.extend(out);
    }
    // The batch path with the stream's placement (floor from frame 0) gives the same rows.
    let encoded = encode_clip(clip.view(), format, 30.0, stream.placement()).unwrap();
    assert_eq!(rows.len(), encoded.features.nrows());
    for (a, b) in rows.iter().zip(encoded.features.outer_iter()) {
        for (x, y) in a.iter().zip(b.iter()) {
            assert_eq!(x, y);
        }
    }
}

#[test]
fn streaming_at_another_rate_resamples_to_the_bundles() {
    let format = JointsFormat {
        fps: 60.0,
        ..Default::default()
    };
    let clip = walking_clip(61, &format);
    let mut stream = FeatureStream::new(format, 30.0, None).unwrap();
    let n: usize = clip
        .outer_iter()
        .map(|f| {
            let predicted = stream.rows_after(1);
            let got = stream.push(f).unwrap().len();
            assert_eq!(predicted, got);
            got
        })
        .sum();
    assert_eq!(
        n, 30,
        "61 frames at 60 fps are 31 at 30 fps, 30 feature frames"
    );
}

#[test]
fn bad_positions_are_refused_naming_frame_and_joint() {
    let format = JointsFormat::default();
    let mut clip = walking_clip(10, &format);
    clip[[4, 13, 1]] = f32::NAN;
    let err = encode_clip(clip.view(), format, 30.0, None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("frame 4") && err.contains("left_collar"),
        "{err}"
    );
    let one = walking_clip(1, &format);
    let err = encode_clip(one.view(), format, 30.0, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("at least 2"), "{err}");
    let wrong = Array3::<f32>::zeros((5, 24, 3));
    assert!(encode_clip(wrong.view(), format, 30.0, None).is_err());
    let slow = JointsFormat { fps: 0.0, ..format };
    assert!(encode_clip(clip.view(), slow, 30.0, None).is_err());
    // A stream refusing a frame keeps its state.
    let good = walking_clip(3, &format);
    let mut stream = FeatureStream::new(format, 30.0, None).unwrap();
    stream.push(good.index_axis(Axis(0), 0)).unwrap();
    assert!(stream.push(clip.index_axis(Axis(0), 4)).is_err());
    assert_eq!(stream.push(good.index_axis(Axis(0), 1)).unwrap().len(), 1);
}
