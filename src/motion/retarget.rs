//! Retargeting: troupe's motion (t2m-22 joint positions, with joint rotations where the source
//! has them) onto a caller's [`Rig`], as that rig's local rotations and root translation.
//!
//! How each rig joint is posed, in troupe's canonical axes (the rig's own units and axes are
//! converted at the boundary):
//! - every rig joint the [`JointMap`] names gets a *world delta* `D` (its posed world rotation
//!   times its rest world rotation's inverse), so the rig's bone axes and rest rotations never
//!   matter: only where its joints are at rest does;
//! - a joint whose nearest mapped descendant is one joint (a limb bone, a spine segment) is
//!   turned by the source joint's world rotation, corrected once for the difference between the
//!   two rest poses (T-pose vs A-pose, a rig facing another way), and then swung so that its
//!   bone points exactly where the source's does: the twist comes from the source when it has
//!   rotations (MAGNet's SMPL-X frames) and is none otherwise (positions carry no twist);
//! - a joint with several mapped descendants (hips, chest) is oriented by the frame its
//!   left/right pair and its up child span, as troupe's own IK does;
//! - mapped joints without mapped descendants (head, hands, toes) follow their mapped ancestor
//!   as the source joint follows its own; joints the map does not name (a root bone, twist
//!   bones, fingers) keep their rest rotation relative to their parent;
//! - the root (the joint mapped to the pelvis) is placed so that the rig's hip centre is where
//!   the source's is, scaled by the ratio of the rigs' leg lengths, troupe's floor moved to the rig's (found beneath its
//!   rest feet), so that feet that stand on troupe's floor stand on the rig's;
//! - hands and feet are then brought onto the source's (scaled) hands and feet by two-bone IK on
//!   shoulder-elbow-wrist and hip-knee-ankle when proportions differ, keeping each limb's bend
//!   plane; a foot in contact is pinned where it landed and released over a few frames when it
//!   lifts, and no foot goes below the rig's floor.
//!
//! Everything is causal and per frame: [`Retargeter::push`] poses one frame as it arrives with no
//! latency added, and [`retarget_clip`] runs the same over a whole clip.

use crate::motion::features::{CONTACT_HEIGHTS, CONTACT_STEP2};
use crate::motion::ik::{two_bone_turns, TwoBoneTurns};
use crate::motion::joint_map::JointMap;
use crate::motion::rig::{Rig, RigPose};
use crate::motion::rotation::Quat;
use crate::motion::skeleton::{Skeleton, T2M22_JOINTS};
use crate::motion::vec3::{add, cross, norm, scale, sub, Vec3};
use crate::motion::world::JointsFormat;
use crate::shared::error::{Error, Result};

/// t2m-22 joints a rig must have for retargeting: pelvis, hips, knees, ankles, shoulders,
/// elbows and wrists.
pub const REQUIRED_JOINTS: [usize; 13] = [0, 1, 2, 4, 5, 7, 8, 16, 17, 18, 19, 20, 21];

/// t2m-22 joints above the pelvis, one of which a rig must have (its spine, neck or head).
const TRUNK_JOINTS: [usize; 5] = [3, 6, 9, 12, 15];

/// Limb chains of t2m-22: upper, middle, end joint (left leg, right leg, left arm, right arm).
const LIMBS: [[usize; 3]; 4] = [[1, 4, 7], [2, 5, 8], [16, 18, 20], [17, 19, 21]];

/// How retargeting treats the feet and limbs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetargetOptions {
    /// Pin a foot where it landed while its contact lasts (no skate added by the retarget);
    /// acts through the legs' IK, so only with `limb_ik`.
    pub foot_lock: bool,
    /// Bring hands and feet onto the source's by two-bone IK when proportions differ.
    pub limb_ik: bool,
    /// Frames over which a lifted foot returns from its pin to the motion.
    pub release_frames: u32,
    /// A pinned foot is let go when the motion's foot is farther than this from the pin, as a
    /// fraction of the rig's leg length (the motion walked away from a contact it declared).
    pub max_pin_stretch: f64,
    /// The source's frame rate (contact speeds are per second).
    pub fps: f32,
}

impl Default for RetargetOptions {
    fn default() -> Self {
        RetargetOptions {
            foot_lock: true,
            limb_ik: true,
            release_frames: 4,
            max_pin_stretch: 0.25,
            fps: 30.0,
        }
    }
}

/// One frame of troupe's motion, in canonical axes (metres, Y up, the floor at 0).
#[derive(Debug, Clone, Copy)]
pub struct SourceFrame<'a> {
    /// The 22 t2m-22 joint positions.
    pub positions: &'a [Vec3],
    /// The 22 joint rotations where the source has them (joint 0's is the root's world
    /// orientation, every other joint's is local to its parent, on the t2m-22 rest pose):
    /// twist about the bones comes from these.
    pub rotations: Option<&'a [Quat]>,
    /// Contacts of left ankle, left foot, right ankle, right foot where the source has them;
    /// otherwise they are found from the ankles' steps and heights (InterGen's thresholds).
    pub contacts: Option<[bool; 4]>,
}

/// How one rig joint is posed.
#[derive(Debug, Clone, Copy)]
enum Aim {
    /// Not named by the map: keeps its rest rotation relative to its parent.
    Unmapped,
    /// Turned like its source joint and swung to point at its one mapped descendant.
    Bone {
        source: usize,
        child: usize,
        child_source: usize,
        correction: Quat,
    },
    /// Oriented by the frame its left/right pair and up descendant span.
    Branch {
        left: (usize, usize),
        right: (usize, usize),
        up: (usize, usize),
        source: usize,
        rest_inverse: Quat,
    },
    /// A mapped joint without mapped descendants: follows its mapped ancestor as its source
    /// joint follows the ancestor's.
    Leaf {
        source: usize,
        anchor: Option<(usize, usize)>,
    },
    /// Turned like its source joint, corrected for the rigs' rest poses only.
    Turned { source: usize, correction: Quat },
}

/// Per-foot state of the foot lock.
#[derive(Debug, Clone, Copy, Default)]
struct FootLock {
    /// Where the foot is pinned while in contact.
    pin: Option<Vec3>,
    /// A release in progress: where it started and the frames done.
    release: Option<(Vec3, u32)>,
    /// The target of the last frame.
    last: Option<Vec3>,
}

/// A retargeter from troupe's t2m-22 motion onto one rig; holds the per-stream state (foot
/// pins, the previous frame), so one per stream.
#[derive(Debug, Clone)]
pub struct Retargeter {
    rig: Rig,
    canonical_rig: Rig,
    source: Skeleton,
    options: RetargetOptions,
    rest_pos: Vec<Vec3>,
    rest_rot: Vec<Quat>,
    aims: Vec<Aim>,
    rig_of: [Option<usize>; T2M22_JOINTS],
    /// The rig joint mapped to the pelvis: the one whose translation moves.
    pelvis: usize,
    /// Source lengths times this are the rig's (its legs over the source's).
    scale: f64,
    /// The height (canonical metres) of the rig's floor, where troupe's floor lands.
    floor: f64,
    /// The lowest each ankle may go: the floor plus the ankle's height above its sole.
    ankle_floor: [f64; 2],
    /// The rig's leg length, metres (how far a pinned foot may be from the motion's).
    leg_length: f64,
    /// Rig joints of the limbs' chains, as [`LIMBS`] lists them.
    limbs: [[usize; 3]; 4],
    /// Joints at or below the pelvis joint (the others stay at rest).
    moves: Vec<bool>,
    feet: [FootLock; 2],
    previous: Option<[Vec3; 2]>,
}

/// The mapped rig joints nearest below `joint` (searching through unmapped ones).
fn frontier(rig: &Rig, mapped: &[Option<usize>], joint: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut stack: Vec<usize> = rig.children(joint).collect();
    stack.reverse();
    while let Some(c) = stack.pop() {
        if mapped[c].is_some() {
            out.push(c);
        } else {
            let mut more: Vec<usize> = rig.children(c).collect();
            more.reverse();
            stack.extend(more);
        }
    }
    out
}

/// World rotations of the source's joints: from its rotations, or by IK on its positions.
fn source_world(source: &Skeleton, frame: &SourceFrame) -> Vec<Quat> {
    let local = match frame.rotations {
        Some(r) => r.to_vec(),
        None => crate::motion::ik::inverse_kinematics(source, frame.positions),
    };
    let mut world = vec![Quat::IDENTITY; source.len()];
    for j in 0..source.len() {
        world[j] = match source.parents()[j] {
            Some(p) => (world[p] * local[j]).normalized(),
            None => local[j].normalized(),
        };
    }
    world
}

impl Retargeter {
    /// A retargeter onto `rig`, whose joints `map` names (rig joints it does not name keep
    /// their rest rotation), from motion on the `source` skeleton (troupe's neutral body,
    /// [`Skeleton::t2m22`], or one [fitted](Skeleton::fitted_to) to the clip). Refused when the
    /// rig lacks a joint of [`REQUIRED_JOINTS`] or has none of the spine, neck and head, or its
    /// legs have no length.
    pub fn new(
        rig: &Rig,
        map: &JointMap,
        source: &Skeleton,
        options: RetargetOptions,
    ) -> Result<Retargeter> {
        let bad = |m: String| Error::InvalidInput(format!("retarget onto {}: {m}", rig.name()));
        if source.len() != T2M22_JOINTS {
            return Err(bad(format!(
                "the source skeleton has {} joints; retargeting takes t2m-22 motion",
                source.len()
            )));
        }
        if !crate::motion::world::FPS_RANGE.contains(&options.fps)
            || !options.max_pin_stretch.is_finite()
            || options.max_pin_stretch <= 0.0
            || options.release_frames > 1000
        {
            return Err(bad(format!(
                "options out of range: fps {} (1 to 1000), max_pin_stretch {} (> 0), \
                 release_frames {} (at most 1000)",
                options.fps, options.max_pin_stretch, options.release_frames
            )));
        }
        let canonical_rig = rig.with_format(JointsFormat::default());
        let (rest_pos, rest_rot) = canonical_rig.rest_world();
        let mut found = map.resolve_partial(rig.names());
        // What the rig's shape says it lacks, when the names leave joints unfound.
        let mut shape_lacks: Vec<usize> = Vec::new();
        if REQUIRED_JOINTS.iter().any(|&j| found[j].is_none()) {
            // The names do not say: recognise the joints by the shape of the rig's rest pose
            // (metres, Y up), if it has a humanoid's.
            let ends = canonical_rig.end_site_positions(&rest_pos, &rest_rot);
            if let Ok(by_shape) =
                crate::motion::shape_map::map_by_shape(rig.names(), rig.parents(), &rest_pos, &ends)
            {
                shape_lacks = REQUIRED_JOINTS
                    .iter()
                    .copied()
                    .filter(|&j| by_shape[j].is_none())
                    .collect();
                if shape_lacks.is_empty() {
                    found = by_shape;
                }
            }
        }
        let t2m = Skeleton::t2m22();
        let missing: Vec<String> = REQUIRED_JOINTS
            .iter()
            .filter(|&&j| found[j].is_none())
            .map(|&j| format!("{} (tried {})", t2m.names()[j], map.names_for(j).join(", ")))
            .collect();
        if !missing.is_empty() {
            // A humanoid without hands (its forearms end at an end site) has nothing to put a
            // hand on: no joint map helps, so the message says what the rig lacks.
            let why = if shape_lacks.is_empty() {
                "give a joint map with your rig's names".to_string()
            } else {
                let lacks: Vec<&str> = shape_lacks
                    .iter()
                    .map(|&j| t2m.names()[j].as_str())
                    .collect();
                format!(
                    "its shape is a humanoid's without {} (a limb ends where that joint would \
                     be), which retargeting needs to drive",
                    lacks.join(", ")
                )
            };
            return Err(bad(format!(
                "the rig has no joint for {}; {why}",
                missing.join("; ")
            )));
        }
        if TRUNK_JOINTS.iter().all(|&j| found[j].is_none()) {
            return Err(bad(
                "the rig has none of the spine, neck and head joints; give a joint map that names one"
                    .into(),
            ));
        }
        let mut rig_of = [None; T2M22_JOINTS];
        rig_of.copy_from_slice(&found);
        let mut mapped = vec![None; rig.len()];
        for (s, r) in found.iter().enumerate() {
            if let Some(r) = r {
                mapped[*r] = Some(s);
            }
        }
        let pelvis = found[0].expect("required");
        for s in REQUIRED_JOINTS.iter().chain(&TRUNK_JOINTS) {
            if let Some(r) = found[*s] {
                if r != pelvis && !is_below(rig, r, pelvis) {
                    return Err(bad(format!(
                        "{} ({}) is not below the pelvis joint {}",
                        rig.names()[r],
                        t2m.names()[*s],
                        rig.names()[pelvis]
                    )));
                }
            }
        }
        let src_rest = source.rest_positions();

        // The rotation taking the rig's rest body frame onto the source's: hips across, spine up.
        let trunk = *frontier(rig, &mapped, pelvis)
            .iter()
            .find(|&&r| TRUNK_JOINTS.contains(&mapped[r].expect("mapped")))
            .ok_or_else(|| {
                bad(format!(
                    "no spine, neck or head joint hangs below the pelvis joint {} other than \
                     through a leg",
                    rig.names()[pelvis]
                ))
            })?;
        let (lh, rh) = (found[1].expect("required"), found[2].expect("required"));
        let rig_body = Quat::from_columns(
            sub(rest_pos[lh], rest_pos[rh]),
            sub(rest_pos[trunk], rest_pos[pelvis]),
        )
        .ok_or_else(|| bad("the rest pose's hips and spine span no frame".into()))?;
        let trunk_src = mapped[trunk].expect("mapped");
        let src_body = Quat::from_columns(
            sub(src_rest[1], src_rest[2]),
            sub(src_rest[trunk_src], src_rest[0]),
        )
        .expect("the source's rest pose spans a frame");
        let align = src_body * rig_body.conj();

        let is_left = |s: usize| t2m.names()[s].starts_with("left_");
        let mirror = |s: usize| -> Option<usize> {
            let name = t2m.names()[s].strip_prefix("left_")?;
            t2m.index_of(&format!("right_{name}"))
        };
        let mut aims = vec![Aim::Unmapped; rig.len()];
        for j in 0..rig.len() {
            let Some(s) = mapped[j] else { continue };
            let below = frontier(rig, &mapped, j);
            let src = |r: usize| mapped[r].expect("frontier joints are mapped");
            let bone = |c: usize| {
                let d_rig = align.rotate(sub(rest_pos[c], rest_pos[j]));
                let d_src = sub(src_rest[src(c)], src_rest[s]);
                Quat::between(d_rig, d_src).map(|q| Aim::Bone {
                    source: s,
                    child: c,
                    child_source: src(c),
                    correction: q * align,
                })
            };
            let pair = below.iter().find_map(|&l| {
                let m = mirror(src(l)).filter(|_| is_left(src(l)))?;
                let r = *below.iter().find(|&&r| src(r) == m)?;
                Some((l, r))
            });
            let up = below
                .iter()
                .copied()
                .find(|&c| pair.is_none_or(|(l, r)| c != l && c != r));
            aims[j] = match (below.len(), pair, up) {
                (0, _, _) => {
                    let mut a = rig.parents()[j];
                    while let Some(p) = a {
                        if mapped[p].is_some() {
                            break;
                        }
                        a = rig.parents()[p];
                    }
                    Aim::Leaf {
                        source: s,
                        anchor: a.map(|a| (a, src(a))),
                    }
                }
                (_, Some((l, r)), Some(u)) => {
                    let rest = Quat::from_columns(
                        sub(rest_pos[l], rest_pos[r]),
                        sub(rest_pos[u], rest_pos[j]),
                    );
                    match rest {
                        Some(rest) => Aim::Branch {
                            left: (l, src(l)),
                            right: (r, src(r)),
                            up: (u, src(u)),
                            source: s,
                            rest_inverse: rest.conj(),
                        },
                        None => bone(u).unwrap_or(Aim::Turned {
                            source: s,
                            correction: align,
                        }),
                    }
                }
                (_, _, Some(u)) => bone(u).unwrap_or(Aim::Turned {
                    source: s,
                    correction: align,
                }),
                _ => Aim::Turned {
                    source: s,
                    correction: align,
                },
            };
        }

        let leg = |hip: usize, knee: usize, ankle: usize, pos: &[Vec3]| {
            norm(sub(pos[knee], pos[hip])) + norm(sub(pos[ankle], pos[knee]))
        };
        let r = |s: usize| found[s].expect("required");
        let rig_leg = 0.5 * (leg(r(1), r(4), r(7), &rest_pos) + leg(r(2), r(5), r(8), &rest_pos));
        let src_leg = 0.5 * (leg(1, 4, 7, &src_rest) + leg(2, 5, 8, &src_rest));
        if !(rig_leg > 1e-6 && src_leg > 1e-6) {
            return Err(bad("the legs have no length at rest".into()));
        }
        let scale_factor = rig_leg / src_leg;
        // The rig's floor: below each rest ankle by the height of the foot beneath it (its
        // lowest joint or end site), or, for a rig without feet below its ankles, by troupe's
        // neutral ankle height scaled. Rest poses need not stand at the origin, nor flat.
        let neutral = Skeleton::t2m22().rest_positions();
        let (canon_pos, canon_rot) = (&rest_pos, &rest_rot);
        // A lowest joint is the ball of the foot, which stands above the sole by as much as
        // troupe's neutral body's (scaled); a lowest end site is the sole.
        let sole = scale_factor * neutral.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
        let ankle_height = |ankle: usize, neutral_height: f64| {
            let mut low = canon_pos[ankle][1] - sole;
            for j in 0..rig.len() {
                if j == ankle || is_below(rig, j, ankle) {
                    low = low.min(canon_pos[j][1] - sole);
                    // (LAFAN1 writes end sites of no length: those are no sole.)
                    if let Some(e) = canonical_rig.end_sites()[j].filter(|e| norm(*e) > 1e-4) {
                        low = low.min(add(canon_pos[j], canon_rot[j].rotate(e))[1]);
                    }
                }
            }
            let h = canon_pos[ankle][1] - low;
            if h < sole + 0.3 * scale_factor * (neutral_height - sole) {
                scale_factor * neutral_height
            } else {
                h
            }
        };
        let heights = [
            ankle_height(r(7), neutral[7][1]),
            ankle_height(r(8), neutral[8][1]),
        ];
        let floor = (rest_pos[r(7)][1] - heights[0]).min(rest_pos[r(8)][1] - heights[1]);
        Ok(Retargeter {
            rig: rig.clone(),
            canonical_rig,
            source: source.clone(),
            options,
            aims,
            rig_of,
            pelvis,
            scale: scale_factor,
            floor,
            ankle_floor: [floor + heights[0], floor + heights[1]],
            leg_length: rig_leg,
            limbs: LIMBS.map(|l| l.map(r)),
            moves: (0..rig.len())
                .map(|j| j == pelvis || is_below(rig, j, pelvis))
                .collect(),
            rest_pos,
            rest_rot,
            feet: [FootLock::default(); 2],
            previous: None,
        })
    }

    /// The rig this retargets onto.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// For each t2m-22 joint, the rig joint it drives (`None`: the rig has none).
    pub fn rig_joints(&self) -> &[Option<usize>; T2M22_JOINTS] {
        &self.rig_of
    }

    /// The factor source lengths are scaled by: the rig's leg length over the source's.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// Where a source point (canonical metres) lands in the rig's world (canonical axes,
    /// metres): scaled about the origin by [`Retargeter::scale`], troupe's floor (height 0)
    /// moved to the rig's (beneath its rest feet).
    pub fn place(&self, p: Vec3) -> Vec3 {
        [
            self.scale * p[0],
            self.scale * p[1] + self.floor,
            self.scale * p[2],
        ]
    }

    /// Forgets the stream: foot pins and the previous frame.
    pub fn reset(&mut self) {
        self.feet = [FootLock::default(); 2];
        self.previous = None;
    }

    /// Poses the rig for the next frame of the stream. Refused (state unchanged) when the
    /// frame does not have 22 finite positions (and, if given, 22 finite rotations).
    pub fn push(&mut self, frame: &SourceFrame) -> Result<RigPose> {
        let bad = |m: &str| Error::InvalidInput(format!("retarget: {m}"));
        if frame.positions.len() != T2M22_JOINTS
            || frame.positions.iter().flatten().any(|v| !v.is_finite())
        {
            return Err(bad("a frame needs 22 finite joint positions"));
        }
        if let Some(r) = frame.rotations {
            if r.len() != T2M22_JOINTS
                || r.iter()
                    .any(|q| ![q.w, q.x, q.y, q.z].iter().all(|v| v.is_finite()))
            {
                return Err(bad("a frame's rotations must be 22 finite quaternions"));
            }
        }
        let p = frame.positions;
        let s_world = source_world(&self.source, frame);
        let n = self.rig.len();
        let mut own: Vec<Option<Quat>> = vec![None; n];
        for j in 0..n {
            own[j] = match self.aims[j] {
                Aim::Unmapped => None,
                Aim::Bone {
                    source,
                    child,
                    child_source,
                    correction,
                } => {
                    let d = s_world[source] * correction;
                    let now = d.rotate(sub(self.rest_pos[child], self.rest_pos[j]));
                    let want = sub(p[child_source], p[source]);
                    Some(Quat::between(now, want).map_or(d, |q| (q * d).normalized()))
                }
                Aim::Branch {
                    left,
                    right,
                    up,
                    source,
                    rest_inverse,
                } => {
                    let posed =
                        Quat::from_columns(sub(p[left.1], p[right.1]), sub(p[up.1], p[source]));
                    Some(posed.map_or_else(
                        || own[self.rig.parents()[j].unwrap_or(j)].unwrap_or(Quat::IDENTITY),
                        |f| (f * rest_inverse).normalized(),
                    ))
                }
                Aim::Leaf { source, anchor } => Some(match anchor {
                    Some((a, a_src)) => {
                        let base = own[a].unwrap_or(Quat::IDENTITY);
                        (base * (s_world[a_src].conj() * s_world[source])).normalized()
                    }
                    None => s_world[source],
                }),
                Aim::Turned { source, correction } => {
                    Some((s_world[source] * correction).normalized())
                }
            };
        }
        let contacts = self.contacts(frame);
        let mut delta = self.propagate(&own);
        // The root goes where it puts the rig's hip centre on the source's (scaled): rigs put
        // their pelvis joint anywhere from the hips' height to the navel, and the legs hang
        // from the hips.
        let hips = |q: &[Vec3], l: usize, r: usize| scale(add(q[l], q[r]), 0.5);
        let rig_hips = sub(
            hips(&self.rest_pos, self.limbs[0][0], self.limbs[1][0]),
            self.rest_pos[self.pelvis],
        );
        let root = sub(
            self.place(hips(p, 1, 2)),
            delta[self.pelvis].rotate(rig_hips),
        );
        let mut pos = self.positions(&delta, root);
        if self.options.limb_ik {
            for (k, limb) in self.limbs.into_iter().enumerate() {
                let [u, m, e] = LIMBS[k];
                let mut target = self.place(p[e]);
                if k < 2 {
                    target = self.foot_target(k, target, contacts[2 * k]);
                }
                let bend_hint = cross(sub(p[e], p[m]), sub(p[u], p[m]));
                two_bone_ik(limb, &pos, target, bend_hint, &mut own);
            }
            delta = self.propagate(&own);
            pos = self.positions(&delta, root);
        }
        self.previous = Some([p[7], p[8]]);
        Ok(self.pose(&delta, &pos))
    }

    /// Contacts of the frame: given, or found causally from the ankles' last step.
    fn contacts(&self, frame: &SourceFrame) -> [bool; 4] {
        if let Some(c) = frame.contacts {
            return c;
        }
        let p = frame.positions;
        // InterGen's step threshold is per frame at 30 fps: a speed.
        let step2 = CONTACT_STEP2 * (30.0 / f64::from(self.options.fps)).powi(2);
        let still = |k: usize, joint: usize| {
            self.previous
                .is_none_or(|prev| norm(sub(p[joint], prev[k])).powi(2) < step2)
        };
        [
            still(0, 7) && p[7][1] < CONTACT_HEIGHTS[0],
            p[10][1] < CONTACT_HEIGHTS[1],
            still(1, 8) && p[8][1] < CONTACT_HEIGHTS[0],
            p[11][1] < CONTACT_HEIGHTS[1],
        ]
    }

    /// Where foot `k`'s ankle goes this frame: the motion's, kept above the floor, pinned while
    /// in contact and released smoothly.
    fn foot_target(&mut self, k: usize, free: Vec3, contact: bool) -> Vec3 {
        let mut free = free;
        free[1] = free[1].max(self.ankle_floor[k]);
        if !self.options.foot_lock {
            return free;
        }
        let lock = &mut self.feet[k];
        let stretch = self.options.max_pin_stretch * self.leg_length;
        let target = match lock.pin {
            Some(pin) if contact && norm(sub(pin, free)) <= stretch => pin,
            Some(pin) => {
                lock.pin = None;
                lock.release = Some((pin, 0));
                free
            }
            None if contact => {
                let at = lock.last.unwrap_or(free);
                lock.pin = Some(at);
                lock.release = None;
                at
            }
            None => free,
        };
        let target = match (lock.pin, lock.release) {
            (None, Some((from, done))) => {
                let total = self.options.release_frames.max(1);
                let done = done + 1;
                lock.release = (done < total).then_some((from, done));
                let t = f64::from(done) / f64::from(total);
                add(scale(from, 1.0 - t), scale(free, t))
            }
            _ => target,
        };
        lock.last = Some(target);
        target
    }

    /// Every joint's world delta: its own where it has one, its parent's otherwise.
    fn propagate(&self, own: &[Option<Quat>]) -> Vec<Quat> {
        let mut delta = vec![Quat::IDENTITY; own.len()];
        for j in 0..own.len() {
            delta[j] = own[j].unwrap_or_else(|| {
                self.canonical_rig.parents()[j].map_or(Quat::IDENTITY, |p| delta[p])
            });
        }
        delta
    }

    /// Canonical world positions of every rig joint with the root at `root` (ancestors of the
    /// root stay at rest).
    fn positions(&self, delta: &[Quat], root: Vec3) -> Vec<Vec3> {
        let mut pos = self.rest_pos.clone();
        for j in 0..pos.len() {
            match self.canonical_rig.parents()[j] {
                _ if j == self.pelvis => pos[j] = root,
                Some(p) if self.moves[j] => {
                    pos[j] = add(
                        pos[p],
                        delta[p].rotate(sub(self.rest_pos[j], self.rest_pos[p])),
                    );
                }
                _ => {}
            }
        }
        pos
    }

    /// The rig pose (rig axes and units) of world deltas and positions.
    fn pose(&self, delta: &[Quat], pos: &[Vec3]) -> RigPose {
        let format = self.rig.format();
        let n = delta.len();
        let world: Vec<Quat> = (0..n).map(|j| delta[j] * self.rest_rot[j]).collect();
        let parents = self.canonical_rig.parents();
        let rotations = (0..n)
            .map(|j| {
                let local = match parents[j] {
                    Some(p) => world[p].conj() * world[j],
                    None => world[j],
                };
                format.rotation_from_canonical_axes(local.normalized())
            })
            .collect();
        let root = self.pelvis;
        let local_translation = match parents[root] {
            Some(p) => world[p].conj().rotate(sub(pos[root], pos[p])),
            None => pos[root],
        };
        RigPose {
            rotations,
            root,
            root_translation: format.point_from_canonical(local_translation),
        }
    }

    /// World positions of a rig pose in canonical axes (metres): [`Rig::posed_positions`].
    pub fn canonical_positions(&self, pose: &RigPose) -> Vec<Vec3> {
        self.rig.posed_positions(pose)
    }
}

/// Whether `joint` lies below `ancestor` in `rig`.
fn is_below(rig: &Rig, joint: usize, ancestor: usize) -> bool {
    let mut at = rig.parents()[joint];
    while let Some(p) = at {
        if p == ancestor {
            return true;
        }
        at = rig.parents()[p];
    }
    false
}

/// Two-bone IK on `[upper, middle, end]` ([`two_bone_turns`]) applied to the rig's world
/// deltas. The end joint keeps its world rotation.
fn two_bone_ik(
    [u, m, e]: [usize; 3],
    pos: &[Vec3],
    target: Vec3,
    bend_hint: Vec3,
    own: &mut [Option<Quat>],
) {
    let Some(TwoBoneTurns { swing, bend }) =
        two_bone_turns([pos[u], pos[m], pos[e]], target, bend_hint)
    else {
        return;
    };
    let end_world = own[e];
    let upper = own[u].unwrap_or(Quat::IDENTITY);
    let middle = own[m].unwrap_or(upper);
    own[u] = Some((swing * upper).normalized());
    own[m] = Some((swing * bend * middle).normalized());
    // Keep the end joint's orientation (its own delta, or what it inherited before).
    own[e] = Some(end_world.unwrap_or(middle));
}

/// A whole clip retargeted (canonical `[frames][22]` positions, optional rotations), with the
/// source skeleton fitted to the clip first so that its proportions, not the neutral body's,
/// set the scale.
pub fn retarget_clip(
    rig: &Rig,
    map: &JointMap,
    positions: &[Vec<Vec3>],
    rotations: Option<&[Vec<Quat>]>,
    options: RetargetOptions,
) -> Result<Vec<RigPose>> {
    if positions.iter().any(|p| p.len() != T2M22_JOINTS) {
        return Err(Error::InvalidInput(
            "retarget: every frame needs 22 joint positions".into(),
        ));
    }
    if rotations.is_some_and(|r| r.len() != positions.len()) {
        return Err(Error::InvalidInput(
            "retarget: one set of rotations per frame".into(),
        ));
    }
    let source = Skeleton::t2m22().fitted_to(positions);
    let mut retargeter = Retargeter::new(rig, map, &source, options)?;
    positions
        .iter()
        .enumerate()
        .map(|(t, p)| {
            retargeter.push(&SourceFrame {
                positions: p,
                rotations: rotations.map(|r| r[t].as_slice()),
                contacts: None,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::ik::forward_kinematics;
    use crate::motion::rig::RigJoint;
    use crate::motion::vec3::{dot, normalize};
    use crate::motion::world::{Units, UpAxis};

    /// A pose of `skeleton`: every joint turned a little, the body moved and turned.
    fn posed(skeleton: &Skeleton, t: f64) -> Vec<Vec3> {
        let local: Vec<Quat> = (0..skeleton.len())
            .map(|j| {
                let a = t + j as f64;
                let axis = normalize([a.sin(), a.cos(), 0.5 * (2.0 * a).sin()]).unwrap();
                Quat::from_axis_angle(axis, 0.5 * (1.3 * a).sin())
            })
            .collect();
        // High enough that no foot reaches the floor (where it would be held).
        forward_kinematics(skeleton, [0.3 + t, 1.9, -1.1], &local)
    }

    fn push(r: &mut Retargeter, p: &[Vec3]) -> RigPose {
        r.push(&SourceFrame {
            positions: p,
            rotations: None,
            contacts: Some([false; 4]),
        })
        .unwrap()
    }

    /// A retargeter onto `rig` with the built-in map, from troupe's neutral body.
    fn onto(rig: &Rig, options: RetargetOptions) -> Retargeter {
        Retargeter::new(rig, &JointMap::builtin(), &Skeleton::t2m22(), options).unwrap()
    }

    /// Options without the limbs' IK.
    fn no_ik() -> RetargetOptions {
        RetargetOptions {
            limb_ik: false,
            ..Default::default()
        }
    }

    fn dist(a: Vec3, b: Vec3) -> f64 {
        norm(sub(a, b))
    }

    #[test]
    fn twist_comes_from_the_source_when_it_has_rotations() {
        let skeleton = Skeleton::t2m22();
        let mut r = onto(&Rig::t2m22(), no_ik());
        for k in 0..8 {
            let t = f64::from(k) * 0.4;
            // Every joint turned, forearms twisted about their own bone as well.
            let mut local: Vec<Quat> = (0..skeleton.len())
                .map(|j| {
                    let a = t + j as f64;
                    let axis = normalize([a.sin(), a.cos(), 0.5 * (2.0 * a).sin()]).unwrap();
                    Quat::from_axis_angle(axis, 0.5 * (1.3 * a).sin())
                })
                .collect();
            for elbow in [18, 19] {
                let bone = normalize(skeleton.offsets()[elbow + 2]).unwrap();
                local[elbow] = local[elbow] * Quat::from_axis_angle(bone, 0.9 + t);
            }
            let positions = forward_kinematics(&skeleton, [0.0, 1.9, 0.0], &local);
            let with = r
                .push(&SourceFrame {
                    positions: &positions,
                    rotations: Some(&local),
                    contacts: Some([false; 4]),
                })
                .unwrap();
            r.reset();
            let without = push(&mut r, &positions);
            r.reset();
            // With rotations, every local rotation is the source's, twist included.
            for (j, q) in with.rotations.iter().enumerate() {
                assert!((dot4(*q, local[j]).abs() - 1.0).abs() < 1e-9, "joint {j}");
            }
            // From positions alone the forearms lose their twist, the positions stay.
            for elbow in [18, 19] {
                assert!((dot4(without.rotations[elbow], local[elbow]).abs() - 1.0).abs() > 1e-3);
            }
            let (a, b) = (
                r.canonical_positions(&with),
                r.canonical_positions(&without),
            );
            for (p, q) in a.iter().zip(&b) {
                assert!(dist(*p, *q) < 1e-9);
            }
        }
    }

    /// MAGNet's SMPL-X frames carry their joints' rotations: retargeted with them onto troupe's
    /// body, every joint's local rotation is the frame's own.
    #[test]
    fn magnet_frames_keep_their_rotations() {
        use crate::motion::rotation::SixD;
        use crate::motion::{smplx145_positions, smplx145_rotations, SMPLX145_DIM};
        let skeleton = Skeleton::t2m22();
        let mut frames = Vec::new();
        for k in 0..4 {
            let mut f = vec![0f32; SMPLX145_DIM];
            for j in 0..22 {
                let a = f64::from(k) * 0.7 + j as f64;
                let axis = normalize([a.cos(), 1.0, a.sin()]).unwrap();
                let q = Quat::from_axis_angle(axis, 0.4 * a.sin());
                let at = if j == 0 { 136 } else { 10 + (j - 1) * 6 };
                for (i, v) in q.to_6d(SixD::ConcatenatedColumns).iter().enumerate() {
                    f[at + i] = *v as f32;
                }
            }
            f[142..145].copy_from_slice(&[0.2, 1.9, -0.4]);
            frames.extend(f);
        }
        let positions = smplx145_positions(&frames, &skeleton).unwrap();
        let rotations = smplx145_rotations(&frames).unwrap();
        let mut r = onto(&Rig::t2m22(), no_ik());
        for (p, q) in positions.iter().zip(&rotations) {
            let pose = r
                .push(&SourceFrame {
                    positions: p,
                    rotations: Some(q),
                    contacts: Some([false; 4]),
                })
                .unwrap();
            for (j, got) in pose.rotations.iter().enumerate() {
                // Single precision in the frames: agreement to their rounding.
                assert!((dot4(*got, q[j]).abs() - 1.0).abs() < 1e-6, "joint {j}");
            }
        }
        assert!(smplx145_rotations(&frames[..100]).is_err());
        let mut nan = frames.clone();
        nan[20] = f32::NAN;
        assert!(smplx145_rotations(&nan).is_err());
    }

    #[test]
    fn onto_troupes_own_body_the_motion_is_reproduced() {
        let skeleton = Skeleton::t2m22();
        for limb_ik in [false, true] {
            let options = RetargetOptions {
                limb_ik,
                ..Default::default()
            };
            let mut r = onto(&Rig::t2m22(), options);
            assert!((r.scale() - 1.0).abs() < 1e-12);
            for k in 0..10 {
                let source = posed(&skeleton, f64::from(k) * 0.3);
                let pose = push(&mut r, &source);
                let got = r.canonical_positions(&pose);
                for (a, b) in source.iter().zip(&got) {
                    assert!(dist(*a, *b) < 1e-9, "ik {limb_ik}: {a:?} vs {b:?}");
                }
            }
        }
    }

    /// troupe's body made into a rig no one would mistake for it: centimetres and Z up, facing
    /// -Z (canonical) at rest, arms in an A-pose, longer legs and shorter arms, a root bone on
    /// the floor above the pelvis, a twist bone in each forearm, a finger on each hand, and rest
    /// rotations on every joint (as glTF rigs have), with LAFAN1/Mixamo-style names.
    fn foreign_rig() -> Rig {
        let t2m = Skeleton::t2m22();
        let names = JointMap::builtin();
        let turn = Quat::from_axis_angle([0.0, 1.0, 0.0], std::f64::consts::PI);
        // World rest positions of the new body, canonical metres.
        let mut world = t2m.rest_positions();
        let rest = world.clone();
        for j in 0..t2m.len() {
            let p = t2m.parents()[j];
            let mut off = p.map_or(rest[j], |p| sub(rest[j], rest[p]));
            let name = &t2m.names()[j];
            if name.contains("knee") || name.contains("ankle") {
                off = scale(off, 1.1);
            }
            if name.contains("elbow") || name.contains("wrist") {
                off = scale(off, 0.9);
                // A-pose: the arm hangs 40° below the horizontal.
                let side = if name.starts_with("left") { -1.0 } else { 1.0 };
                off = Quat::from_axis_angle([0.0, 0.0, 1.0], side * 0.7).rotate(off);
            }
            world[j] = p.map_or(off, |p| add(world[p], off));
        }
        let world: Vec<Vec3> = world.iter().map(|&w| turn.rotate(w)).collect();
        // Joints: root bone, then t2m joints (with twist bones and fingers after them).
        struct J {
            name: String,
            parent: Option<usize>,
            world: Vec3,
        }
        let mut joints = vec![J {
            name: "Root".into(),
            parent: None,
            world: [0.0; 3],
        }];
        let mut index = vec![0; t2m.len()];
        for j in 0..t2m.len() {
            let mut parent = t2m.parents()[j].map_or(0, |p| index[p]);
            if t2m.names()[j].contains("wrist") {
                let twist = J {
                    name: format!("{}Twist", names.names_for(j)[0]),
                    parent: Some(parent),
                    world: scale(add(joints[parent].world, world[j]), 0.5),
                };
                joints.push(twist);
                parent = joints.len() - 1;
            }
            joints.push(J {
                name: names.names_for(j)[0].clone(),
                parent: Some(parent),
                world: world[j],
            });
            index[j] = joints.len() - 1;
            if t2m.names()[j].contains("wrist") {
                let dir = sub(world[j], world[t2m.parents()[j].unwrap()]);
                joints.push(J {
                    name: format!("{}Finger", names.names_for(j)[0]),
                    parent: Some(index[j]),
                    world: add(world[j], scale(dir, 0.3)),
                });
            }
        }
        // Rest rotations: each joint's world rest rotation some arbitrary turn; offsets then
        // expressed in the parent's rotated frame, all in Z-up centimetres.
        let format = JointsFormat {
            units: Units::Centimeters,
            up: UpAxis::Z,
            ..Default::default()
        };
        let world_rot: Vec<Quat> = (0..joints.len())
            .map(|j| {
                let a = j as f64 * 0.7;
                Quat::from_axis_angle(normalize([a.cos(), 1.0, a.sin()]).unwrap(), a)
            })
            .collect();
        let rig_joints = joints
            .iter()
            .enumerate()
            .map(|(j, joint)| {
                let (offset, rotation) = match joint.parent {
                    Some(p) => (
                        world_rot[p]
                            .conj()
                            .rotate(sub(joint.world, joints[p].world)),
                        world_rot[p].conj() * world_rot[j],
                    ),
                    None => (joint.world, world_rot[j]),
                };
                RigJoint {
                    name: joint.name.clone(),
                    parent: joint.parent,
                    offset: format.point_from_canonical(offset),
                    rotation: format.rotation_from_canonical_axes(rotation),
                    end_site: None,
                }
            })
            .collect();
        Rig::new("foreign", rig_joints, format).unwrap()
    }

    #[test]
    fn a_foreign_rig_follows_bone_directions_and_reaches_hands_and_feet() {
        let skeleton = Skeleton::t2m22();
        let rig = foreign_rig();
        for limb_ik in [false, true] {
            let options = RetargetOptions {
                limb_ik,
                ..Default::default()
            };
            let mut r = onto(&rig, options);
            let joints = *r.rig_joints();
            for k in 0..10 {
                let source = posed(&skeleton, f64::from(k) * 0.3);
                let pose = push(&mut r, &source);
                let got = r.canonical_positions(&pose);
                let at = |s: usize| got[joints[s].unwrap()];
                let centre = |a: Vec3, b: Vec3| scale(add(a, b), 0.5);
                let hips = r.place(centre(source[1], source[2]));
                assert!(dist(centre(at(1), at(2)), hips) < 1e-9, "hip centre placed");
                // The body faces the source's way: its left hip on the source's left.
                let across = sub(at(1), at(2));
                assert!(dot(across, sub(source[1], source[2])) > 0.0);
                if limb_ik {
                    for [u, m, e] in LIMBS {
                        let target = r.place(source[e]);
                        let (l1, l2) = (dist(at(m), at(u)), dist(at(e), at(m)));
                        let reach = dist(target, at(u));
                        let err = if reach < l1 + l2 - 1e-5 {
                            dist(at(e), target)
                        } else {
                            // Out of reach: the limb stretched straight towards it.
                            let toward = normalize(sub(target, at(u))).unwrap();
                            dist(at(e), add(at(u), scale(toward, l1 + l2)))
                        };
                        assert!(err < 1e-5, "end joint {e}: {err} m from its target");
                    }
                } else {
                    // Every mapped bone points the source's way.
                    for (c, p) in [(4, 1), (7, 4), (18, 16), (20, 18), (12, 9), (9, 6)] {
                        let a = normalize(sub(at(c), at(p))).unwrap();
                        let b = normalize(sub(source[c], source[p])).unwrap();
                        assert!(dot(a, b) > 1.0 - 1e-9, "bone {p}->{c}: {a:?} vs {b:?}");
                    }
                }
                // Unmapped joints keep their rest rotation relative to their parent.
                let twist = rig
                    .names()
                    .iter()
                    .position(|n| n.ends_with("Twist"))
                    .unwrap();
                let rest = rig.rest_rotations()[twist];
                let q = pose.rotations[twist];
                assert!((dot4(q, rest).abs() - 1.0).abs() < 1e-9);
            }
        }
    }

    fn dot4(a: Quat, b: Quat) -> f64 {
        a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z
    }

    /// The neutral body with bent knees, ankles at their rest height: a pinned foot is then
    /// within the leg's reach.
    fn crouch(skeleton: &Skeleton) -> Vec<Vec3> {
        let mut local = vec![Quat::IDENTITY; skeleton.len()];
        for (joint, angle) in [
            (1, -0.4),
            (2, -0.4),
            (4, 0.8),
            (5, 0.8),
            (7, -0.4),
            (8, -0.4),
        ] {
            local[joint] = Quat::from_axis_angle([1.0, 0.0, 0.0], angle);
        }
        let rest = skeleton.rest_positions();
        let bent = forward_kinematics(skeleton, rest[0], &local);
        let drop = bent[7][1] - rest[7][1];
        bent.iter().map(|p| sub(*p, [0.0, drop, 0.0])).collect()
    }

    #[test]
    fn a_foot_in_contact_stays_where_it_landed_and_is_released_smoothly() {
        let skeleton = Skeleton::t2m22();
        let mut r = onto(&foreign_rig(), RetargetOptions::default());
        let ankle = r.rig_joints()[7].unwrap();
        let rest = crouch(&skeleton);
        let mut track = Vec::new();
        for t in 0..20 {
            // The whole body slides 1 cm a frame along x: a skating stand.
            let p: Vec<Vec3> = rest
                .iter()
                .map(|&q| add(q, [0.01 * f64::from(t), 0.0, 0.0]))
                .collect();
            let contact = t < 10;
            let pose = r
                .push(&SourceFrame {
                    positions: &p,
                    rotations: None,
                    contacts: Some([contact, false, contact, false]),
                })
                .unwrap();
            track.push((r.canonical_positions(&pose)[ankle], r.place(p[7])));
        }
        for t in 1..10 {
            assert!(
                dist(track[t].0, track[0].0) < 1e-6,
                "frame {t}: the foot slid"
            );
        }
        // Released over 4 frames: steps bounded, then back on the motion.
        for t in 10..14 {
            assert!(dist(track[t].0, track[t - 1].0) < 0.05, "frame {t}: a jump");
        }
        for (t, (got, want)) in track.iter().enumerate().skip(14) {
            assert!(
                dist(*got, *want) < 1e-6,
                "frame {t}: not back on the motion"
            );
        }
    }

    #[test]
    fn contacts_are_found_from_the_ankles_when_not_given() {
        let skeleton = Skeleton::t2m22();
        let mut r = onto(&Rig::t2m22(), RetargetOptions::default());
        let rest = crouch(&skeleton);
        let mut first = None;
        for t in 0..5 {
            // 5 mm a frame at 30 fps is standing; the foot is on the floor.
            let p: Vec<Vec3> = rest
                .iter()
                .map(|&q| add(q, [0.005 * f64::from(t), 0.0, 0.0]))
                .collect();
            let pose = r
                .push(&SourceFrame {
                    positions: &p,
                    rotations: None,
                    contacts: None,
                })
                .unwrap();
            let at = r.canonical_positions(&pose)[7];
            let first = *first.get_or_insert(at);
            assert!(dist(at, first) < 1e-6, "frame {t}: not pinned");
        }
    }

    #[test]
    fn bad_frames_and_rigs_are_refused_and_leave_the_stream_as_it_was() {
        let skeleton = Skeleton::t2m22();
        let mut r = onto(&Rig::t2m22(), RetargetOptions::default());
        let good = skeleton.rest_positions();
        let mut nan = good.clone();
        nan[3][1] = f64::NAN;
        let before = format!("{:?}", r.feet);
        assert!(r
            .push(&SourceFrame {
                positions: &nan,
                rotations: None,
                contacts: None,
            })
            .unwrap_err()
            .to_string()
            .contains("finite"));
        assert!(r
            .push(&SourceFrame {
                positions: &good[..21],
                rotations: None,
                contacts: None,
            })
            .is_err());
        let short = vec![Quat::IDENTITY; 3];
        assert!(r
            .push(&SourceFrame {
                positions: &good,
                rotations: Some(&short),
                contacts: None,
            })
            .is_err());
        assert_eq!(before, format!("{:?}", r.feet));
        assert!(r.previous.is_none());
        // A rig without arms names what it lacks.
        let legs_only = Rig::new(
            "legs",
            (0..9)
                .filter(|j| ![3, 6].contains(j))
                .map(|j| RigJoint {
                    name: skeleton.names()[j].clone(),
                    parent: skeleton.parents()[j].map(|p| [0, 1, 2, 0, 3, 4, 0, 5, 6][p]),
                    offset: skeleton.offsets()[j],
                    rotation: Quat::IDENTITY,
                    end_site: None,
                })
                .collect(),
            JointsFormat::default(),
        )
        .unwrap();
        let err = Retargeter::new(
            &legs_only,
            &JointMap::builtin(),
            &skeleton,
            Default::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("left_shoulder (tried LeftArm"), "{err}");
    }
}
