//! BVH (Biovision Hierarchy) files: read as motion-capture tools write them, and written for
//! the t2m-22 skeleton or a caller's rig.
//!
//! Why troupe reads BVH itself: the one Rust BVH crate (`bvh_anim`) calls itself alpha quality
//! and has not been released since 2020, and a runtime embedded in other programs needs what it
//! does not promise: allocation bounded by the file's size before anything is allocated, and
//! errors that name the file, line, joint and frame.
//!
//! Conventions (those of the format's authors and of Blender, MotionBuilder and the CMU, LAFAN1
//! and Mixamo files): a joint's rotation channels apply in the order listed, as intrinsic
//! rotations (`Zrotation Xrotation Yrotation` is `Rz · Rx · Ry`), in degrees; a joint with
//! position channels is placed at those values instead of its `OFFSET`; a joint's world
//! transform is its parent's times its own.

mod parse;
mod rig;
mod write;
mod write_rig;

pub use parse::{
    parse_bvh, read_bvh, MAX_BVH_BYTES, MAX_BVH_COORDINATE, MAX_BVH_JOINTS, MAX_BVH_NAME_BYTES,
};
pub(crate) use write::euler_zyx_degrees;
pub use write::{write_bvh, write_bvh_file, BvhPerson, BvhWriteOptions};
pub use write_rig::{write_rig_bvh, write_rig_bvh_file};

use ndarray::Array3;

use crate::motion::joint_inference::{JointSource, RigShape};
use crate::motion::joint_map::JointMap;
use crate::motion::rotation::Quat;
use crate::motion::shape_map::{standing_axis, z_up_to_y_up};
use crate::motion::vec3::{add, Vec3};
use crate::motion::world::{JointsFormat, Units, UpAxis};
use crate::shared::error::{Error, Result};
use crate::shared::logging::{log, Level};

/// One channel of a BVH joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// Translation along x.
    XPosition,
    /// Translation along y.
    YPosition,
    /// Translation along z.
    ZPosition,
    /// Rotation about x, degrees.
    XRotation,
    /// Rotation about y, degrees.
    YRotation,
    /// Rotation about z, degrees.
    ZRotation,
}

impl Channel {
    /// The channel's name as BVH files write it.
    pub fn name(self) -> &'static str {
        match self {
            Channel::XPosition => "Xposition",
            Channel::YPosition => "Yposition",
            Channel::ZPosition => "Zposition",
            Channel::XRotation => "Xrotation",
            Channel::YRotation => "Yrotation",
            Channel::ZRotation => "Zrotation",
        }
    }

    fn parse(token: &str) -> Option<Channel> {
        Some(match token.to_ascii_lowercase().as_str() {
            "xposition" => Channel::XPosition,
            "yposition" => Channel::YPosition,
            "zposition" => Channel::ZPosition,
            "xrotation" => Channel::XRotation,
            "yrotation" => Channel::YRotation,
            "zrotation" => Channel::ZRotation,
            _ => return None,
        })
    }

    /// The unit axis of a rotation channel, or `None` for a position channel.
    fn rotation_axis(self) -> Option<Vec3> {
        match self {
            Channel::XRotation => Some([1.0, 0.0, 0.0]),
            Channel::YRotation => Some([0.0, 1.0, 0.0]),
            Channel::ZRotation => Some([0.0, 0.0, 1.0]),
            _ => None,
        }
    }
}

/// A joint of a BVH hierarchy.
#[derive(Debug, Clone, PartialEq)]
pub struct BvhJoint {
    /// The joint's name.
    pub name: String,
    /// Its parent's index (`None` for the root).
    pub parent: Option<usize>,
    /// Offset from the parent, in the file's units.
    pub offset: Vec3,
    /// Its channels, in file order.
    pub channels: Vec<Channel>,
    /// The offset of its `End Site`, if it has one.
    pub end_site: Option<Vec3>,
}

/// A parsed BVH file: the hierarchy and every frame's channel values.
#[derive(Debug, Clone, PartialEq)]
pub struct Bvh {
    /// Joints in file order (parents before children).
    pub joints: Vec<BvhJoint>,
    /// Seconds per frame.
    pub frame_time: f64,
    /// Channel values, `frames × channels` in file order.
    pub values: Vec<f32>,
    /// Channels per frame (the sum over joints).
    pub channels_per_frame: usize,
}

impl Bvh {
    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.values
            .len()
            .checked_div(self.channels_per_frame)
            .unwrap_or(0)
    }

    /// Frames per second, as the author meant them: `1 / frame_time`, or the whole or NTSC
    /// rate it is within 1e-4 of ([`crate::motion::world::rate_meant`]; `0.0333333` s is 30 fps).
    pub fn fps(&self) -> f64 {
        crate::motion::world::rate_meant(1.0 / self.frame_time)
    }

    /// The index of the joint called `name`.
    pub fn joint(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Every joint's world position in every frame (`[frames, joints, 3]`, file units and
    /// axes), by forward kinematics.
    pub fn positions(&self) -> Array3<f32> {
        let (n, frames) = (self.joints.len(), self.frames());
        let mut out = Array3::<f32>::zeros((frames, n, 3));
        for t in 0..frames {
            let (pos, _) = self.pose(t);
            for (j, p) in pos.iter().enumerate() {
                for d in 0..3 {
                    out[[t, j, d]] = p[d] as f32;
                }
            }
        }
        out
    }

    /// World positions of every joint and of its end site, where it has one, in frame `t`
    /// (file units and axes).
    fn pose_with_end_sites(&self, t: usize) -> (Vec<Vec3>, Vec<Option<Vec3>>) {
        let (pos, rot) = self.pose(t);
        let ends = self
            .joints
            .iter()
            .enumerate()
            .map(|(j, joint)| joint.end_site.map(|e| add(pos[j], rot[j].rotate(e))))
            .collect();
        (pos, ends)
    }

    /// World positions and rotations of every joint in frame `t` (file units and axes).
    fn pose(&self, t: usize) -> (Vec<Vec3>, Vec<Quat>) {
        let n = self.joints.len();
        let mut world_rot = vec![Quat::IDENTITY; n];
        let mut world_pos = vec![[0.0f64; 3]; n];
        let row = &self.values[t * self.channels_per_frame..(t + 1) * self.channels_per_frame];
        let mut at = 0;
        for (j, joint) in self.joints.iter().enumerate() {
            let (translation, rotation) = local_transform(joint, &row[at..]);
            at += joint.channels.len();
            let (pos, rot) = match joint.parent {
                Some(p) => (
                    add(world_pos[p], world_rot[p].rotate(translation)),
                    world_rot[p] * rotation,
                ),
                None => (translation, rotation),
            };
            world_pos[j] = pos;
            world_rot[j] = rot;
        }
        (world_pos, world_rot)
    }
}

/// A BVH clip as t2m-22 joint positions, with the format that says how to read them.
#[derive(Debug, Clone)]
pub struct BvhJoints {
    /// `[frames, 22, 3]` positions in the file's units, Y up (a file whose figure stands along
    /// Z, as Blender writes BVH, is turned Y up).
    pub positions: Array3<f32>,
    /// The file's units (declared or guessed), Y up, right-handed, and its frame rate.
    pub format: JointsFormat,
    /// The t2m-22 joints the rig lacks and how they were placed, one line each (empty when the
    /// rig has them all).
    pub inferred: Vec<String>,
    /// For each t2m-22 joint, the rig joint it is read from, by name; `None` where it is placed
    /// from other joints (`inferred` says how). Which joint became which, by names or by shape.
    pub mapping: Vec<Option<String>>,
}

impl Bvh {
    /// The t2m-22 joints of this clip: `map` says which rig joint each is, and joints the rig
    /// lacks are placed from the others ([`crate::motion::joint_inference`]; `inferred` says
    /// which and how). `label` names the file in messages. `units`: the file's length unit, or `None` to guess it from the
    /// figure's height in the first frame (above 10 units: centimetres, else metres). BVH is Y
    /// up by convention; a figure that stands only along Z (Blender's exporter writes its Z-up
    /// armature space as it is) is read Z up and turned, and the log says so.
    pub fn to_t2m22(&self, map: &JointMap, units: Option<Units>, label: &str) -> Result<BvhJoints> {
        let frames = self.frames();
        if frames == 0 {
            return Err(Error::InvalidInput(format!(
                "{label}: the file has no frames"
            )));
        }
        let fps = self.fps();
        if !crate::motion::world::FPS_RANGE.contains(&(fps as f32)) {
            return Err(Error::InvalidInput(format!(
                "{label}: Frame Time {} s is {fps} fps, outside [1, 1000]",
                self.frame_time
            )));
        }
        if fps != 1.0 / self.frame_time {
            log(Level::Info, "troupe::motion", || {
                format!(
                    "{label}: Frame Time {} s read as {} fps",
                    self.frame_time,
                    (fps * 1000.0).round() / 1000.0
                )
            });
        }
        let names: Vec<String> = self.joints.iter().map(|j| j.name.clone()).collect();
        let parents: Vec<Option<usize>> = self.joints.iter().map(|j| j.parent).collect();
        let end_sites: Vec<bool> = self.joints.iter().map(|j| j.end_site.is_some()).collect();
        // The first frame, a standing person in a mocap file, shows the rig's shape, and the
        // axis it stands along: Y by convention, Z as Blender's exporter writes (turned Y up).
        let (first_pose, first_ends) = self.pose_with_end_sites(0);
        let z_up = standing_axis(&names, &parents, &first_pose, &first_ends) == UpAxis::Z;
        if z_up {
            log(Level::Info, "troupe::motion", || {
                format!(
                    "{label}: the figure stands along Z, not Y: read Z up (as Blender writes BVH)"
                )
            });
        }
        let pose_at = |t: usize| {
            let (mut pos, mut ends) = self.pose_with_end_sites(t);
            if z_up {
                pos.iter_mut().for_each(|p| *p = z_up_to_y_up(*p));
                ends.iter_mut()
                    .flatten()
                    .for_each(|p| *p = z_up_to_y_up(*p));
            }
            (pos, ends)
        };
        let (first_pose, first_ends) = pose_at(0);
        let resolved = map.resolve_inferring(
            RigShape {
                names: &names,
                parents: &parents,
                end_sites: &end_sites,
                pose: &first_pose,
                pose_end_sites: &first_ends,
            },
            label,
        )?;
        let mut positions = Array3::<f32>::zeros((frames, resolved.sources.len(), 3));
        for t in 0..frames {
            let (pos, ends) = pose_at(t);
            for (k, source) in resolved.sources.iter().enumerate() {
                let p = source.position(&pos, &ends);
                for d in 0..3 {
                    positions[[t, k, d]] = p[d] as f32;
                }
            }
        }
        let units = units.unwrap_or_else(|| units_from_height(first_pose.iter().map(|p| p[1])));
        let mapping = resolved
            .sources
            .iter()
            .map(|source| match source {
                JointSource::Joint(j) => Some(names[*j].clone()),
                JointSource::Along { .. } => None,
            })
            .collect();
        Ok(BvhJoints {
            positions,
            mapping,
            inferred: resolved.inferred,
            format: JointsFormat {
                units,
                fps: fps as f32,
                ..JointsFormat::default()
            },
        })
    }
}

/// A file's units guessed from the heights of its joints (in one pose): a figure more than 10
/// units tall is in centimetres, else in metres.
fn units_from_height(heights: impl Iterator<Item = f64>) -> Units {
    let (lo, hi) = heights.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if hi - lo > 10.0 {
        Units::Centimeters
    } else {
        Units::Meters
    }
}

/// A joint's translation and rotation relative to its parent from its channel values.
fn local_transform(joint: &BvhJoint, values: &[f32]) -> (Vec3, Quat) {
    let mut translation = joint.offset;
    let mut rotation = Quat::IDENTITY;
    for (c, v) in joint.channels.iter().zip(values) {
        let v = f64::from(*v);
        match c {
            Channel::XPosition => translation[0] = v,
            Channel::YPosition => translation[1] = v,
            Channel::ZPosition => translation[2] = v,
            _ => {
                let axis = c.rotation_axis().expect("rotation channel");
                rotation = rotation * Quat::from_axis_angle(axis, v.to_radians());
            }
        }
    }
    (translation, rotation)
}
