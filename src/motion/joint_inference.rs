//! t2m-22 joints a rig does not have, placed from the joints it does have.
//!
//! Rigs differ from troupe's body in more than names: two spine joints instead of three, no
//! toes (the foot ends in an end site), no collar bones, a forearm ending where the hand would
//! be. Reading such a rig's motion as t2m-22 positions places each missing joint on the rig,
//! per frame, from what is there (and says so):
//! - spine joints (and the neck) along the rig's chain from the nearest mapped joint below to
//!   the nearest above, at the fractions of that chain's length troupe's neutral body puts them;
//! - a toe (the ball of the foot) from the ankle towards the end of the foot (its end site, or
//!   the end of its unmapped child chain), where troupe's body has it;
//! - a collar between the top of the spine and the shoulder, where troupe's body has it;
//! - a wrist, ankle or head at the end of the bone before it (the forearm's, shin's or neck's end
//!   site or unmapped child).
//!
//! Joints it cannot place (a rig without legs, say) are named in the error, with the names that
//! were tried.

use crate::motion::joint_map::JointMap;
use crate::motion::skeleton::Skeleton;
use crate::motion::vec3::{add, norm, scale, sub, Vec3};
use crate::shared::error::{Error, Result};

/// A point of a posed rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RigPoint {
    /// A joint.
    Joint(usize),
    /// The end site of a joint.
    EndSite(usize),
}

/// Where a t2m-22 joint comes from on a rig.
#[derive(Debug, Clone, PartialEq)]
pub enum JointSource {
    /// A rig joint the map names.
    Joint(usize),
    /// A fraction `at` of the way along a chain of rig points (by length, per frame).
    Along {
        /// The chain, from its first point to its last.
        chain: Vec<RigPoint>,
        /// How far along, in [0, 1].
        at: f64,
    },
}

/// The t2m-22 joints of a rig: where each comes from, and a sentence per inferred joint.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedJoints {
    /// One source per t2m-22 joint, in skeleton order.
    pub sources: Vec<JointSource>,
    /// What was inferred and how, one line per joint (empty when the rig had every joint).
    pub inferred: Vec<String>,
}

/// A rig's hierarchy as inference needs it.
#[derive(Debug, Clone, Copy)]
pub struct RigShape<'a> {
    /// Joint names.
    pub names: &'a [String],
    /// Each joint's parent.
    pub parents: &'a [Option<usize>],
    /// Whether each joint has an end site.
    pub end_sites: &'a [bool],
    /// One pose of the rig, each joint's position, Y up (a standing person: a mocap file's first
    /// frame), for recognising its joints by their shape when the names do not say (empty: names
    /// only).
    pub pose: &'a [Vec3],
    /// Each joint's end site in that pose, where it has one (empty with an empty `pose`).
    pub pose_end_sites: &'a [Option<Vec3>],
}

impl RigShape<'_> {
    fn children(&self, j: usize) -> Vec<usize> {
        (0..self.names.len())
            .filter(|&c| self.parents[c] == Some(j))
            .collect()
    }

    /// The rig joints from `from` down to `to` (inclusive), if `to` is below `from`.
    fn path(&self, from: usize, to: usize) -> Option<Vec<usize>> {
        let mut up = vec![to];
        let mut at = to;
        while at != from {
            at = self.parents[at]?;
            up.push(at);
        }
        up.reverse();
        Some(up)
    }

    /// Where the bone of joint `j` ends when nothing mapped is below it: its end site, or the
    /// end of its chain of single unmapped children.
    fn bone_end(&self, j: usize, mapped: &[bool]) -> Option<Vec<RigPoint>> {
        let mut chain = vec![RigPoint::Joint(j)];
        let mut at = j;
        loop {
            let children = self.children(at);
            match children.as_slice() {
                [] => {
                    if self.end_sites[at] {
                        chain.push(RigPoint::EndSite(at));
                    }
                    break;
                }
                [c] if !mapped[*c] => {
                    chain.push(RigPoint::Joint(*c));
                    at = *c;
                }
                _ => return None,
            }
        }
        (chain.len() > 1).then_some(chain)
    }
}

/// How far `joint` lies along the chain of t2m-22 joints `chain` (which holds it) in troupe's
/// neutral body, as a fraction of the chain's length.
fn neutral_fraction(chain: &[usize], joint: usize) -> f64 {
    let rest = Skeleton::t2m22().rest_positions();
    let mut lengths = vec![0.0];
    for w in chain.windows(2) {
        let last = lengths[lengths.len() - 1];
        lengths.push(last + norm(sub(rest[w[1]], rest[w[0]])));
    }
    let i = chain
        .iter()
        .position(|&c| c == joint)
        .expect("the joint is in the chain");
    lengths[i] / lengths[lengths.len() - 1]
}

/// The point of a chain of positions a fraction `at` along its length.
pub fn along(points: &[Vec3], at: f64) -> Vec3 {
    let lengths: Vec<f64> = points.windows(2).map(|w| norm(sub(w[1], w[0]))).collect();
    let total: f64 = lengths.iter().sum();
    if total <= 0.0 {
        return points[0];
    }
    let mut left = at.clamp(0.0, 1.0) * total;
    for (i, l) in lengths.iter().enumerate() {
        if left <= *l || i + 1 == lengths.len() {
            let t = if *l > 0.0 { (left / l).min(1.0) } else { 0.0 };
            return add(points[i], scale(sub(points[i + 1], points[i]), t));
        }
        left -= l;
    }
    points[points.len() - 1]
}

// t2m-22 joint indices.
const PELVIS: usize = 0;
const SPINE: [usize; 3] = [3, 6, 9];
const NECK: usize = 12;
const HEAD: usize = 15;
/// (toe, ankle) per side.
const TOES: [(usize, usize); 2] = [(10, 7), (11, 8)];
/// (collar, shoulder) per side.
const COLLARS: [(usize, usize); 2] = [(13, 16), (14, 17)];
/// (end joint, its parent in the chain) that may be a bone's end: ankles, wrists, head.
const BONE_ENDS: [(usize, usize); 5] = [(7, 4), (8, 5), (20, 18), (21, 19), (15, 12)];

impl JointMap {
    /// Where each t2m-22 joint comes from on `rig`: its own joint where the map names one,
    /// else inferred (see the module documentation). An error names every joint that cannot be
    /// placed and the names tried (`label` names the rig).
    ///
    /// When the names leave joints that cannot be placed, the rig's joints are recognised from
    /// the shape of its hierarchy in `rig.pose` instead (`shape_map`), and the first line of
    /// `inferred` says so and which joint became which.
    pub fn resolve_inferring(&self, rig: RigShape, label: &str) -> Result<ResolvedJoints> {
        let by_names = self.resolve_partial(rig.names);
        let named_error = match self.place(rig, by_names, label) {
            Ok(resolved) => return Ok(resolved),
            Err(Error::InvalidInput(message)) if rig.pose.len() == rig.names.len() => message,
            Err(e) => return Err(e),
        };
        let by_shape = match crate::motion::shape_map::map_by_shape(
            rig.names,
            rig.parents,
            rig.pose,
            rig.pose_end_sites,
        ) {
            Ok(found) => found,
            Err(why) => {
                return Err(Error::InvalidInput(format!(
                    "{named_error}; nor can its joints be recognised by their shape: {why}"
                )))
            }
        };
        let t2m = Skeleton::t2m22();
        let said: Vec<String> = by_shape
            .iter()
            .enumerate()
            .filter_map(|(j, f)| f.map(|i| format!("{} {}", t2m.names()[j], rig.names[i])))
            .collect();
        let mut resolved = self.place(rig, by_shape, label)?;
        resolved.inferred.insert(
            0,
            format!(
                "joints recognised by the rig's shape, its names not being known: {}",
                said.join(", ")
            ),
        );
        Ok(resolved)
    }

    /// [`JointMap::resolve_inferring`] with the rig joints `found` for each t2m-22 joint.
    fn place(
        &self,
        rig: RigShape,
        found: Vec<Option<usize>>,
        label: &str,
    ) -> Result<ResolvedJoints> {
        let t2m = Skeleton::t2m22();
        let mut mapped = vec![false; rig.names.len()];
        for i in found.iter().flatten() {
            mapped[*i] = true;
        }
        let mut sources: Vec<Option<JointSource>> =
            found.iter().map(|f| f.map(JointSource::Joint)).collect();
        let mut inferred = Vec::new();
        let name = |j: usize| t2m.names()[j].clone();
        let rig_name = |p: &RigPoint| match p {
            RigPoint::Joint(i) => rig.names[*i].clone(),
            RigPoint::EndSite(i) => format!("{}'s end site", rig.names[*i]),
        };

        // Bones that end where a t2m joint should be (Rigify's forearm without a hand).
        for (end, before) in BONE_ENDS {
            if sources[end].is_some() {
                continue;
            }
            if let Some(chain) = found[before].and_then(|b| rig.bone_end(b, &mapped)) {
                inferred.push(format!(
                    "{} at the end of {} ({})",
                    name(end),
                    rig.names[found[before].expect("checked")],
                    rig_name(chain.last().expect("a chain of two points or more"))
                ));
                sources[end] = Some(JointSource::Along { chain, at: 1.0 });
            }
        }
        // Spine joints and the neck: along the rig's chain between mapped trunk joints.
        let trunk = [PELVIS, SPINE[0], SPINE[1], SPINE[2], NECK, HEAD];
        for k in 1..trunk.len() - 1 {
            let joint = trunk[k];
            if sources[joint].is_some() {
                continue;
            }
            let below = trunk[..k].iter().rev().find(|&&t| found[t].is_some());
            let above = trunk[k + 1..].iter().find(|&&t| found[t].is_some());
            let (Some(&lo), Some(&hi)) = (below, above) else {
                continue;
            };
            let Some(path) = rig.path(found[lo].expect("found"), found[hi].expect("found")) else {
                continue;
            };
            let index = |t: usize| trunk.iter().position(|&x| x == t).expect("in the trunk");
            let at = neutral_fraction(&trunk[index(lo)..=index(hi)], joint);
            inferred.push(format!(
                "{} at {:.2} of the way from {} to {}",
                name(joint),
                at,
                rig.names[found[lo].expect("found")],
                rig.names[found[hi].expect("found")]
            ));
            sources[joint] = Some(JointSource::Along {
                chain: path.into_iter().map(RigPoint::Joint).collect(),
                at,
            });
        }
        // Toes: from the ankle towards the end of the foot.
        let rest = t2m.rest_positions();
        for (toe, ankle) in TOES {
            if sources[toe].is_some() {
                continue;
            }
            let Some(a) = found[ankle] else { continue };
            if let Some(chain) = rig.bone_end(a, &mapped) {
                // troupe's ball of the foot is 0.75 of the way to the toe tip.
                inferred.push(format!(
                    "{} three quarters of the way from {} to {}",
                    name(toe),
                    rig.names[a],
                    rig_name(chain.last().expect("two points or more"))
                ));
                sources[toe] = Some(JointSource::Along { chain, at: 0.75 });
            }
        }
        // Collars: between the top of the spine and the shoulder.
        for (collar, shoulder) in COLLARS {
            if sources[collar].is_some() {
                continue;
            }
            let top = [SPINE[2], SPINE[1], SPINE[0]]
                .into_iter()
                .find_map(|t| found[t].map(|i| (t, i)));
            let (Some((t, top)), Some(sh)) = (top, found[shoulder]) else {
                continue;
            };
            let (c, s) = (rest[collar], rest[shoulder]);
            let at = norm(sub(c, rest[t])) / (norm(sub(c, rest[t])) + norm(sub(s, c)));
            inferred.push(format!(
                "{} at {at:.2} of the way from {} to {}",
                name(collar),
                rig.names[top],
                rig.names[sh]
            ));
            sources[collar] = Some(JointSource::Along {
                chain: vec![RigPoint::Joint(top), RigPoint::Joint(sh)],
                at,
            });
        }
        let missing: Vec<String> = sources
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_none())
            .map(|(j, _)| format!("{} (tried {})", name(j), self.names_for(j).join(", ")))
            .collect();
        if !missing.is_empty() {
            return Err(Error::InvalidInput(format!(
                "{label}: no joint of this rig is the t2m-22 joint {}, and it cannot be placed \
                 from the others; extend the joint map with your rig's names",
                missing.join("; ")
            )));
        }
        Ok(ResolvedJoints {
            sources: sources.into_iter().map(|s| s.expect("checked")).collect(),
            inferred,
        })
    }
}

impl JointSource {
    /// This joint's position given the rig's joint positions and end-site positions.
    pub fn position(&self, joints: &[Vec3], end_sites: &[Option<Vec3>]) -> Vec3 {
        match self {
            JointSource::Joint(i) => joints[*i],
            JointSource::Along { chain, at } => {
                let points: Vec<Vec3> = chain
                    .iter()
                    .map(|p| match p {
                        RigPoint::Joint(i) => joints[*i],
                        RigPoint::EndSite(i) => end_sites[*i].unwrap_or(joints[*i]),
                    })
                    .collect();
                along(&points, *at)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_along_a_chain_is_by_length() {
        let points = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 3.0]];
        assert_eq!(along(&points, 0.0), [0.0, 0.0, 0.0]);
        assert_eq!(along(&points, 0.25), [0.0, 1.0, 0.0]);
        assert_eq!(along(&points, 0.5), [0.0, 1.0, 1.0]);
        assert_eq!(along(&points, 1.0), [0.0, 1.0, 3.0]);
    }

    #[test]
    fn neutral_fractions_follow_the_chain() {
        let f = neutral_fraction(&[0, 3, 6, 9, 12], 6);
        assert!(f > 0.3 && f < 0.7, "{f}");
        assert_eq!(neutral_fraction(&[0, 3, 6], 0), 0.0);
        assert!((neutral_fraction(&[0, 3, 6], 6) - 1.0).abs() < 1e-12);
    }
}
