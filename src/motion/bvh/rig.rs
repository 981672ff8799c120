//! A BVH file's hierarchy as a [`Rig`]: the character retargeting poses and writers write.

use super::{local_transform, units_from_height, Bvh};
use crate::motion::rig::{Rig, RigJoint};
use crate::motion::rotation::Quat;
use crate::motion::shape_map::standing_axis;
use crate::motion::world::{JointsFormat, Units, UpAxis};
use crate::shared::error::{excerpt, Error, Result};
use crate::shared::logging::{log, Level};

impl Bvh {
    /// The rig of this file's hierarchy: its offsets at rest (no channel applied), no rest
    /// rotations, Y up (or Z up for a figure that stands only that way, as Blender's exporter
    /// writes). `units`: the file's unit, or `None` to guess it from the rest pose's height
    /// (above 10 units: centimetres, else metres). `name` names the rig.
    pub fn rig(&self, units: Option<Units>, name: &str) -> Result<Rig> {
        let joints = self
            .joints
            .iter()
            .map(|j| RigJoint {
                name: j.name.clone(),
                parent: j.parent,
                offset: j.offset,
                rotation: Quat::IDENTITY,
                end_site: j.end_site,
            })
            .collect();
        standing(name, joints, units)
    }

    /// The rig of this file's hierarchy posed as in frame `frame`: for files whose all-zero
    /// pose is no standing pose (LAFAN1's lies on its side), a frame where the figure stands
    /// gives the rest pose retargeting measures from. Joints with position channels take those
    /// positions as their offsets. `units` and `name` as in [`Bvh::rig`].
    pub fn rig_at_frame(&self, frame: usize, units: Option<Units>, name: &str) -> Result<Rig> {
        if frame >= self.frames() {
            return Err(Error::InvalidInput(format!(
                "rig {}: frame {frame} of a file of {} frames",
                excerpt(name),
                self.frames()
            )));
        }
        let row =
            &self.values[frame * self.channels_per_frame..(frame + 1) * self.channels_per_frame];
        let mut at = 0;
        let mut joints = Vec::with_capacity(self.joints.len());
        for joint in &self.joints {
            let (offset, rotation) = local_transform(joint, &row[at..]);
            at += joint.channels.len();
            joints.push(RigJoint {
                name: joint.name.clone(),
                parent: joint.parent,
                offset,
                rotation: rotation.normalized(),
                end_site: joint.end_site,
            });
        }
        standing(name, joints, units)
    }
}

/// The rig of `joints` in the axes its rest pose stands along: Y up, as BVH files are by
/// convention, or Z up for a figure that stands only that way (Blender's BVH exporter writes its
/// armature's space, Z up, unconverted), said in the log. `units`: declared, or guessed from the
/// height along that axis.
fn standing(name: &str, joints: Vec<RigJoint>, units: Option<Units>) -> Result<Rig> {
    let y_up = Rig::new(name, joints.clone(), JointsFormat::default())?;
    let (pos, rot) = y_up.rest_world();
    let ends = y_up.end_site_positions(&pos, &rot);
    let up = standing_axis(y_up.names(), y_up.parents(), &pos, &ends);
    if up == UpAxis::Z {
        log(Level::Info, "troupe::motion", || {
            format!(
                "rig {}: its rest pose stands along Z, not Y: read Z up (as Blender writes BVH)",
                excerpt(name)
            )
        });
    }
    let axis = if up == UpAxis::Z { 2 } else { 1 };
    let units = units.unwrap_or_else(|| units_from_height(pos.iter().map(|p| p[axis])));
    Rig::new(
        name,
        joints,
        JointsFormat {
            units,
            up,
            ..JointsFormat::default()
        },
    )
}
