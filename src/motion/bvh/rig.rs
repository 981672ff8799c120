//! A BVH file's hierarchy as a [`Rig`]: the character retargeting poses and writers write.

use super::{local_transform, units_from_height, Bvh};
use crate::motion::rig::{Rig, RigJoint};
use crate::motion::rotation::Quat;
use crate::motion::vec3::{add, Vec3};
use crate::motion::world::{JointsFormat, Units};
use crate::shared::error::{excerpt, Error, Result};

impl Bvh {
    /// The rig of this file's hierarchy: its offsets at rest (no channel applied), no rest
    /// rotations, Y up. `units`: the file's unit, or `None` to guess it from the rest pose's
    /// height (above 10 units: centimetres, else metres). `name` names the rig.
    pub fn rig(&self, units: Option<Units>, name: &str) -> Result<Rig> {
        let joints: Vec<RigJoint> = self
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
        let units = units.unwrap_or_else(|| {
            let mut world: Vec<Vec3> = Vec::with_capacity(joints.len());
            for j in &joints {
                let p = j.parent.map_or([0.0; 3], |p| world[p]);
                world.push(add(p, j.offset));
            }
            units_from_height(world.iter().map(|p| p[1]))
        });
        Rig::new(
            name,
            joints,
            JointsFormat {
                units,
                ..JointsFormat::default()
            },
        )
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
        let zero = self.rig(units, name)?;
        let mut at = 0;
        let mut joints = Vec::with_capacity(self.joints.len());
        for (j, joint) in self.joints.iter().enumerate() {
            let (offset, rotation) = local_transform(joint, &row[at..]);
            at += joint.channels.len();
            joints.push(RigJoint {
                name: joint.name.clone(),
                parent: joint.parent,
                offset,
                rotation: rotation.normalized(),
                end_site: zero.end_sites()[j],
            });
        }
        Rig::new(name, joints, zero.format())
    }
}
