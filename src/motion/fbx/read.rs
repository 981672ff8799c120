//! Reading FBX with ufbx (see the module above for how a file becomes a clip).

use std::path::Path;

use super::{MAX_FBX_BYTES, MAX_FBX_NODE_FRAMES, MAX_FBX_VALUES};
use crate::motion::bvh::{
    Bvh, BvhJoint, Channel, MAX_BVH_COORDINATE, MAX_BVH_JOINTS, MAX_BVH_NAME_BYTES,
};
use crate::motion::features::MAX_CLIP_FRAMES;
use crate::motion::rotation::Quat;
use crate::motion::vec3::{sub, Vec3};
use crate::motion::world::Units;
use crate::shared::error::{excerpt, Error, Result};
use crate::shared::progress;

/// Reads an FBX file as a skeleton's clip, refusing anything that is not a regular file of at
/// most [`MAX_FBX_BYTES`]. `units`: the unit the clip is given in (the file's own is converted
/// to it); `None` for metres.
pub fn read_fbx(path: impl AsRef<Path>, units: Option<Units>) -> Result<Bvh> {
    let path = path.as_ref();
    let bytes = crate::shared::files::read_bounded(path, MAX_FBX_BYTES, "FBX files")?;
    parse_fbx(&bytes, &path.display().to_string(), units)
}

/// Parses an FBX file's bytes (`label` names it in messages). `units` as in [`read_fbx`].
pub fn parse_fbx(bytes: &[u8], label: &str, units: Option<Units>) -> Result<Bvh> {
    let invalid = |what: String| Error::InvalidInput(format!("{label}: {what}"));
    if bytes.len() as u64 > MAX_FBX_BYTES {
        return Err(invalid(format!(
            "{} bytes; troupe reads FBX files of at most {MAX_FBX_BYTES}",
            bytes.len()
        )));
    }
    let scene = load(bytes, units.unwrap_or(Units::Meters))
        .map_err(|e| invalid(format!("not a readable FBX file: {e}")))?;
    Skeleton::of(&scene, label)?.clip(&scene, label)
}

/// The scene of an FBX file, converted to Y up, right-handed, in `units`; geometry, embedded
/// files and external files are not loaded, and ufbx's memory is capped in proportion to the
/// file.
fn load(bytes: &[u8], units: Units) -> std::result::Result<ufbx::SceneRoot, String> {
    let cap = (bytes.len().saturating_mul(32)).clamp(64 << 20, 2 << 30);
    let allocator = || ufbx::AllocatorOpts {
        memory_limit: cap,
        ..Default::default()
    };
    let opts = ufbx::LoadOpts {
        temp_allocator: allocator(),
        result_allocator: allocator(),
        ignore_geometry: true,
        ignore_embedded: true,
        load_external_files: false,
        target_axes: ufbx::CoordinateAxes {
            right: ufbx::CoordinateAxis::PositiveX,
            up: ufbx::CoordinateAxis::PositiveY,
            front: ufbx::CoordinateAxis::PositiveZ,
        },
        target_unit_meters: units.meters(),
        space_conversion: ufbx::SpaceConversion::TransformRoot,
        ..Default::default()
    };
    ufbx::load_memory(bytes, opts).map_err(|e| {
        let info = e.info();
        let detail = if info.is_empty() {
            String::new()
        } else {
            format!(" ({})", excerpt(info))
        };
        format!("{}{detail}", excerpt(&e.description))
    })
}

/// The bones of a scene that become joints, in an order where parents come first.
struct Skeleton {
    /// Scene node index of each joint.
    nodes: Vec<usize>,
    joints: Vec<BvhJoint>,
    /// Scene node index of each joint's end-site bone, if it has one.
    end_nodes: Vec<Option<usize>>,
}

impl Skeleton {
    fn of(scene: &ufbx::Scene, label: &str) -> Result<Skeleton> {
        let invalid = |what: String| Error::InvalidInput(format!("{label}: {what}"));
        let is_bone = |node: &ufbx::Node| node.bone.is_some();
        let bones: Vec<usize> = (0..scene.nodes.len())
            .filter(|&i| is_bone(&scene.nodes[i]))
            .collect();
        if bones.is_empty() {
            return Err(invalid(
                "the file has no skeleton (no bones, FBX `LimbNode`s)".to_string(),
            ));
        }
        if bones.len() > MAX_BVH_JOINTS {
            return Err(invalid(format!(
                "{} bones; troupe reads rigs of at most {MAX_BVH_JOINTS}",
                bones.len()
            )));
        }
        // Scene nodes are listed parents first (ufbx sorts them by depth), so walking in that
        // order sees a bone's parent before the bone.
        let bone_parent = |i: usize| {
            let mut at = scene.nodes[i].parent.as_ref();
            while let Some(node) = at {
                if is_bone(node) {
                    return Some(node.element.typed_id as usize);
                }
                at = node.parent.as_ref();
            }
            None
        };
        let has_bone_child = |i: usize| scene.nodes[i].children.iter().any(|child| is_bone(child));
        let mut skeleton = Skeleton {
            nodes: Vec::new(),
            joints: Vec::new(),
            end_nodes: Vec::new(),
        };
        let mut joint_of: Vec<Option<usize>> = vec![None; scene.nodes.len()];
        for &i in &bones {
            let node = &scene.nodes[i];
            let name = node.element.name.to_string();
            if name.len() > MAX_BVH_NAME_BYTES || name.chars().any(char::is_control) {
                return Err(invalid(format!(
                    "bone name `{}`: names are at most {MAX_BVH_NAME_BYTES} bytes without control \
                     characters",
                    excerpt(&name)
                )));
            }
            let parent = bone_parent(i).and_then(|p| joint_of[p]);
            if let Some(p) = parent {
                if !has_bone_child(i) && is_end_marker(&name) && skeleton.end_nodes[p].is_none() {
                    skeleton.end_nodes[p] = Some(i);
                    continue;
                }
            }
            if skeleton.joints.iter().any(|j| j.name == name) {
                return Err(invalid(format!(
                    "two bones are called `{}`; troupe tells joints apart by name",
                    excerpt(&name)
                )));
            }
            joint_of[i] = Some(skeleton.joints.len());
            skeleton.nodes.push(i);
            skeleton.end_nodes.push(None);
            skeleton.joints.push(BvhJoint {
                name,
                parent,
                offset: [0.0; 3],
                channels: Vec::new(),
                end_site: None,
            });
        }
        Ok(skeleton)
    }

    /// The clip: rest offsets from the scene's own transforms, then every frame of the first
    /// animation stack sampled at the file's rate.
    fn clip(mut self, scene: &ufbx::Scene, label: &str) -> Result<Bvh> {
        let invalid = |what: String| Error::InvalidInput(format!("{label}: {what}"));
        // The file's own pose (the scene as loaded), and the rest pose read from it.
        let file = self.world(scene, label)?;
        let rest = self.rest(scene, file.clone(), label)?;
        let (rest_pos, rest_rot) = (&rest.0, &rest.1);
        for (j, joint) in self.joints.iter_mut().enumerate() {
            joint.offset = match joint.parent {
                Some(p) => sub(rest_pos[j], rest_pos[p]),
                None => rest_pos[j],
            };
        }
        // A tip keeps its place in its joint's frame: read it there in the file's pose, put it
        // at rest (leaf bones rarely have a bind pose of their own).
        let (file_pos, file_rot) = &file;
        for (j, end) in self.end_nodes.iter().enumerate() {
            if let Some(e) = end {
                let tip = position(&scene.nodes[*e].node_to_world);
                check_finite(tip, label)?;
                let local = file_rot[j].conj().rotate(sub(tip, file_pos[j]));
                self.joints[j].end_site = Some(rest_rot[j].rotate(local));
            }
        }
        let fps = scene.settings.frames_per_second;
        let stack = scene.anim_stacks.iter().next();
        let frames: Vec<(Vec<Vec3>, Vec<Quat>)> = match stack {
            Some(stack) if (1.0..=1000.0).contains(&fps) => {
                // The stack's own span, or (a stack that states none) its curves' keys.
                let (mut begin, mut end) = (stack.time_begin, stack.time_end);
                if (end - begin).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    (begin, end) = scene
                        .anim_curves
                        .iter()
                        .filter(|c| !c.keyframes.is_empty())
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(b, e), c| {
                            (b.min(c.min_time), e.max(c.max_time))
                        });
                }
                let span = end - begin;
                let count = if span.is_finite() && span > 0.0 {
                    (span * fps).round() + 1.0
                } else {
                    begin = stack.time_begin;
                    1.0
                };
                let per_frame = self.joints.len() * 6;
                if count * per_frame as f64 > MAX_FBX_VALUES as f64 {
                    return Err(invalid(format!(
                        "{count} frames of {} bones; troupe reads at most {MAX_FBX_VALUES} values",
                        self.joints.len()
                    )));
                }
                // Each frame evaluates the whole scene: bound the work, not only the values.
                let work = count * scene.nodes.len() as f64;
                if count > MAX_CLIP_FRAMES as f64 || work > MAX_FBX_NODE_FRAMES as f64 {
                    return Err(invalid(format!(
                        "{count} frames of a scene of {} nodes; troupe reads at most \
                         {MAX_CLIP_FRAMES} frames and {MAX_FBX_NODE_FRAMES} nodes × frames",
                        scene.nodes.len()
                    )));
                }
                let mut frames = Vec::with_capacity(count as usize);
                for t in 0..count as usize {
                    // A long file can be stopped: progress every 4096 frames.
                    if t % 4096 == 4095 {
                        progress::report("reading the FBX", t as u64 + 1, count as u64)?;
                    }
                    let time = begin + t as f64 / fps;
                    let posed = ufbx::evaluate_scene(scene, &stack.anim, time, Default::default())
                        .map_err(|e| invalid(format!("frame {t} cannot be evaluated: {e:?}")))?;
                    frames.push(self.world(&posed, label)?);
                }
                frames
            }
            Some(_) => {
                return Err(invalid(format!(
                    "a frame rate of {fps} fps, outside [1, 1000]"
                )))
            }
            None => vec![rest.clone()],
        };
        let fps = if stack.is_some() { fps } else { 30.0 };
        // Each joint's turn away from its rest orientation, in world axes; then local.
        let turns: Vec<Vec<Quat>> = frames
            .iter()
            .map(|(_, rot)| {
                rot.iter()
                    .zip(rest_rot)
                    .map(|(now, rest)| (*now * rest.conj()).normalized())
                    .collect()
            })
            .collect();
        // Joints whose distance from their parent moves (beyond float noise) are translated.
        let scale = rest_pos
            .iter()
            .flat_map(|p| p.iter())
            .fold(1e-3f64, |m, v| m.max(v.abs()));
        let moves: Vec<bool> = self
            .joints
            .iter()
            .enumerate()
            .map(|(j, joint)| match joint.parent {
                None => true,
                Some(p) => frames.iter().zip(&turns).any(|((pos, _), turn)| {
                    let local = turn[p].conj().rotate(sub(pos[j], pos[p]));
                    let d = sub(local, joint.offset);
                    d.iter().any(|v| v.abs() > 1e-5 * scale)
                }),
            })
            .collect();
        for (joint, moving) in self.joints.iter_mut().zip(&moves) {
            if *moving {
                joint
                    .channels
                    .extend([Channel::XPosition, Channel::YPosition, Channel::ZPosition]);
            }
            joint
                .channels
                .extend([Channel::ZRotation, Channel::YRotation, Channel::XRotation]);
        }
        let channels_per_frame: usize = self.joints.iter().map(|j| j.channels.len()).sum();
        let mut values = Vec::with_capacity(frames.len() * channels_per_frame);
        for ((pos, _), turn) in frames.iter().zip(&turns) {
            for (j, joint) in self.joints.iter().enumerate() {
                let (translation, local) = match joint.parent {
                    Some(p) => (
                        turn[p].conj().rotate(sub(pos[j], pos[p])),
                        turn[p].conj() * turn[j],
                    ),
                    None => (pos[j], turn[j]),
                };
                if moves[j] {
                    values.extend(translation.iter().map(|v| *v as f32));
                }
                values.extend(
                    crate::motion::bvh::euler_zyx_degrees(local)
                        .iter()
                        .map(|v| *v as f32),
                );
            }
        }
        Ok(Bvh {
            joints: self.joints,
            frame_time: 1.0 / fps,
            values,
            channels_per_frame,
        })
    }

    /// The rest pose: each bone's bind pose where the file has one (written with skinned
    /// meshes: the pose they were bound in), else its own transform in the file.
    /// `file` is the joints' pose in the loaded scene.
    fn rest(
        &self,
        scene: &ufbx::Scene,
        file: (Vec<Vec3>, Vec<Quat>),
        label: &str,
    ) -> Result<(Vec<Vec3>, Vec<Quat>)> {
        let (mut pos, mut rot) = file;
        for (j, &i) in self.nodes.iter().enumerate() {
            let node = &scene.nodes[i];
            let Some(pose) = node.bind_pose.as_ref() else {
                continue;
            };
            let bound = pose
                .bone_poses
                .iter()
                .find(|b| b.bone_node.element.typed_id == node.element.typed_id);
            if let Some(bound) = bound {
                let p = position(&bound.bone_to_world);
                check_finite(p, label)?;
                pos[j] = p;
                rot[j] = orientation(&bound.bone_to_world);
            }
        }
        Ok((pos, rot))
    }

    /// World positions and orientations of the joints in `scene` (the loaded scene, or one
    /// evaluated at a time).
    fn world(&self, scene: &ufbx::Scene, label: &str) -> Result<(Vec<Vec3>, Vec<Quat>)> {
        let mut pos = Vec::with_capacity(self.nodes.len());
        let mut rot = Vec::with_capacity(self.nodes.len());
        for &i in &self.nodes {
            let m = &scene.nodes[i].node_to_world;
            let p = position(m);
            check_finite(p, label)?;
            pos.push(p);
            rot.push(orientation(m));
        }
        Ok((pos, rot))
    }
}

/// Whether a childless bone's name marks a tip rather than a joint: Blender's `_end` leaf
/// bones, Mixamo's `HeadTop_End`, 3ds Max's `Nub`s.
fn is_end_marker(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    lower.ends_with("end") || lower.ends_with("nub")
}

fn position(m: &ufbx::Matrix) -> Vec3 {
    [m.m03, m.m13, m.m23]
}

/// The rotation of a node-to-world matrix, its columns' scale divided out (a column of zero
/// length, a bone scaled to nothing, counts as unscaled).
fn orientation(m: &ufbx::Matrix) -> Quat {
    let mut columns = [
        [m.m00, m.m10, m.m20],
        [m.m01, m.m11, m.m21],
        [m.m02, m.m12, m.m22],
    ];
    for c in &mut columns {
        let n = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        if n.is_finite() && n > 1e-12 {
            c.iter_mut().for_each(|v| *v /= n);
        }
    }
    let rows = [
        [columns[0][0], columns[1][0], columns[2][0]],
        [columns[0][1], columns[1][1], columns[2][1]],
        [columns[0][2], columns[1][2], columns[2][2]],
    ];
    let q = Quat::from_matrix(rows).normalized();
    if q.to_wxyz().iter().all(|v| v.is_finite()) {
        q
    } else {
        Quat::IDENTITY
    }
}

fn check_finite(p: Vec3, label: &str) -> Result<()> {
    if p.iter()
        .all(|v| v.is_finite() && v.abs() <= MAX_BVH_COORDINATE)
    {
        Ok(())
    } else {
        Err(Error::InvalidInput(format!(
            "{label}: a bone lies at {p:?}, beyond troupe's ±{MAX_BVH_COORDINATE}"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn end_markers_are_the_tips_exporters_add() {
        for name in [
            "head_end",
            "mixamorig:HeadTop_End",
            "Bip01 L Toe0Nub",
            "DEF-toe.L_end",
        ] {
            assert!(is_end_marker(name), "{name}");
        }
        for name in ["Head", "mixamorig:LeftFoot", "spine_03"] {
            assert!(!is_end_marker(name), "{name}");
        }
    }

    #[test]
    fn garbage_is_refused_with_the_file_named() {
        let e = parse_fbx(b"Kaydara FBX Binary  \x00garbage", "bad.fbx", None).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("bad.fbx") && text.contains("not a readable FBX"),
            "{text}"
        );
    }
}
