//! A rig's t2m-22 joints recognised from the shape of its hierarchy, for rigs whose names the
//! joint map does not know (or knows wrongly: `LeftShoulder` is Mixamo's collar but another
//! rig's upper arm).
//!
//! From one pose of the rig (a standing person, Y up):
//! - the **pelvis** is the first joint, from the root down, that branches into a chain rising
//!   highest (the spine) and two chains ending well below it (the legs);
//! - the **spine** runs from the pelvis up to the first joint with three or more branches (the
//!   chest: the neck and the two arms); its first joint is `spine1`, the chest `spine3`, a joint
//!   between them `spine2` (a spine of one or two joints leaves the others to be placed along
//!   it);
//! - the **neck** is the chest's branch that rises highest; the head is the joint after the
//!   neck (a joint called "head" further along the chain is preferred);
//! - the **arms** are the chest's two longest other branches, the **legs** the pelvis's two
//!   lowest; in each limb the two longest consecutive bones are the upper and lower limb
//!   (shoulder, elbow, wrist; hip, knee, ankle), a joint before them is the collar and a joint
//!   after the ankle the toes;
//! - **left** is the side the rig's left hand would be on facing the way its feet point (its
//!   toes; +Z without them), with "left"/"right" in the names breaking a tie.
//!
//! Names only break ties, so a rig named in any language maps the same. A hierarchy without
//! that shape (a chain, a quadruped whose spine does not rise above its hips, several people in
//! one file) is refused with the reason.

use crate::motion::vec3::{norm, sub, Vec3};
use crate::motion::world::UpAxis;

// t2m-22 joint indices.
const PELVIS: usize = 0;
const HIPS: [usize; 2] = [1, 2];
const KNEES: [usize; 2] = [4, 5];
const ANKLES: [usize; 2] = [7, 8];
const TOES: [usize; 2] = [10, 11];
const SPINE: [usize; 3] = [3, 6, 9];
const NECK: usize = 12;
const HEAD: usize = 15;
const COLLARS: [usize; 2] = [13, 14];
const SHOULDERS: [usize; 2] = [16, 17];
const ELBOWS: [usize; 2] = [18, 19];
const WRISTS: [usize; 2] = [20, 21];

/// A rig's hierarchy in one pose, with what the search needs of each joint's subtree computed
/// once (bottom up: rigs may have many joints, so nothing here recurses or rescans a subtree).
struct Posed<'a> {
    children: Vec<Vec<usize>>,
    points: &'a [Vec3],
    /// Each joint's end site, where it has one.
    ends: &'a [Option<Vec3>],
    /// The lowest and highest heights of each joint's subtree.
    reach: Vec<(f64, f64)>,
    /// The length of the longest path of bones down each joint's subtree, and its next joint.
    longest: Vec<(f64, Option<usize>)>,
}

impl<'a> Posed<'a> {
    /// `None` unless every joint's parent comes before it (as in a BVH file).
    fn new(
        parents: &[Option<usize>],
        points: &'a [Vec3],
        ends: &'a [Option<Vec3>],
    ) -> Option<Self> {
        let n = parents.len();
        let mut children = vec![Vec::new(); n];
        for (j, p) in parents.iter().enumerate() {
            if let Some(p) = *p {
                if p >= j {
                    return None;
                }
                children[p].push(j);
            }
        }
        let mut reach: Vec<(f64, f64)> = points.iter().map(|p| (p[1], p[1])).collect();
        let mut longest = vec![(0.0, None); n];
        for j in (0..n).rev() {
            if let Some(p) = parents[j] {
                reach[p] = (reach[p].0.min(reach[j].0), reach[p].1.max(reach[j].1));
                let through = longest[j].0 + norm(sub(points[j], points[p]));
                if through > longest[p].0 {
                    longest[p] = (through, Some(j));
                }
            }
        }
        Some(Self {
            children,
            points,
            ends,
            reach,
            longest,
        })
    }

    fn height(&self, j: usize) -> f64 {
        self.points[j][1]
    }

    /// The longest path of bones from `j` down its subtree.
    fn longest_path(&self, j: usize) -> Vec<usize> {
        let mut path = vec![j];
        while let Some(next) = self.longest[path[path.len() - 1]].1 {
            path.push(next);
        }
        path
    }

    /// The chain from `j` down, always into the child `key` ranks first.
    fn follow(&self, j: usize, key: impl Fn(usize) -> f64) -> Vec<usize> {
        let mut chain = vec![j];
        while let Some(&next) = self.children[chain[chain.len() - 1]]
            .iter()
            .max_by(|&&a, &&b| key(a).total_cmp(&key(b)))
        {
            chain.push(next);
        }
        chain
    }

    fn bone(&self, a: usize, b: usize) -> f64 {
        norm(sub(self.points[b], self.points[a]))
    }

    /// The index `i` where the bones from point `i` of `chain` to point `i + 2` are the
    /// longest consecutive pair (the upper and lower limb), if the chain has two bones. The
    /// chain's points are its joints and then the last one's end site, if it has one (a forearm
    /// without a hand ends there): points `i` and `i + 1` are always joints.
    fn limb(&self, chain: &[usize]) -> Option<usize> {
        let mut points: Vec<Vec3> = chain.iter().map(|&j| self.points[j]).collect();
        points.extend(chain.last().and_then(|&j| self.ends[j]));
        let bone = |i: usize| norm(sub(points[i + 1], points[i]));
        (0..points.len().checked_sub(2)?)
            .max_by(|&a, &b| (bone(a) + bone(a + 1)).total_cmp(&(bone(b) + bone(b + 1))))
    }
}

/// `chain` without the joints that only split a bone in two (Rigify's deform limbs, `DEF-
/// upper_arm.L` then its twist half `DEF-upper_arm.L.001`): a joint named as its parent in the
/// chain with something added, lying on the line of its parent's bone and its own. Such a joint
/// is no elbow or knee, and left in, its halves would be taken for the limb's two bones.
fn without_splits(chain: &[usize], names: &[String], points: &[Vec3]) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::with_capacity(chain.len());
    for (i, &j) in chain.iter().enumerate() {
        let split = match (kept.last(), chain.get(i + 1)) {
            (Some(&parent), Some(&next)) => {
                let (a, b) = (sub(points[j], points[parent]), sub(points[next], points[j]));
                let along = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
                let (own, parents) = (names[j].as_str(), names[parent].as_str());
                let named = own.len() > parents.len() && own.starts_with(parents);
                // Within 10 degrees of one line.
                named && along > 0.985 * norm(a) * norm(b)
            }
            _ => false,
        };
        if !split {
            kept.push(j);
        }
    }
    kept
}

/// Which side a name says, if it says one: +1 left, -1 right.
fn side_named(name: &str) -> f64 {
    let lower = name.rsplit(':').next().unwrap_or(name).to_ascii_lowercase();
    let says = |marks: &[&str], prefix: &str, suffixes: &[&str]| {
        marks.iter().any(|m| lower.contains(m))
            || lower.starts_with(prefix)
            || suffixes.iter().any(|s| lower.ends_with(s))
    };
    if says(&["left"], "l_", &["_l", ".l", "-l"]) {
        1.0
    } else if says(&["right"], "r_", &["_r", ".r", "-r"]) {
        -1.0
    } else {
        0.0
    }
}

/// For each t2m-22 joint, the rig joint the shape of `names`/`parents` in the pose `points`
/// (one per joint, Y up; `ends`, each joint's end site in that pose, where it has one) says it
/// is (`None`: the rig has no such joint, to be placed from its neighbours), or why the rig is
/// not a humanoid.
pub(crate) fn map_by_shape(
    names: &[String],
    parents: &[Option<usize>],
    points: &[Vec3],
    ends: &[Option<Vec3>],
) -> std::result::Result<Vec<Option<usize>>, String> {
    let n = names.len();
    if points.len() != n || ends.len() != n {
        return Err("the pose does not have a point per joint".into());
    }
    let rig = Posed::new(parents, points, ends)
        .ok_or("its joints are not listed parents first, as a BVH file lists them")?;
    let (lowest, highest) = (0..n)
        .filter(|&j| parents[j].is_none())
        .map(|r| rig.reach[r])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, b)| {
            (lo.min(a), hi.max(b))
        });
    let tall = highest - lowest;
    if tall.is_nan() || tall <= 0.0 {
        return Err("the rig has no height in its first pose".into());
    }
    // The pelvis: the first joint (breadth first) with a branch rising highest and two others
    // ending a quarter of the figure's height below it. Below a pelvis the search stops (a chest
    // with hanging arms has that shape too); a second pelvis elsewhere is a second person.
    let mut queue: Vec<usize> = (0..n).filter(|&j| parents[j].is_none()).collect();
    let mut found = Vec::new();
    let mut i = 0;
    while i < queue.len() {
        let j = queue[i];
        i += 1;
        let kids = &rig.children[j];
        let pelvis = (kids.len() >= 3).then(|| {
            let spine = *kids
                .iter()
                .max_by(|&&a, &&b| rig.reach[a].1.total_cmp(&rig.reach[b].1))
                .expect("three children");
            let mut legs: Vec<usize> = kids
                .iter()
                .copied()
                .filter(|&c| c != spine && rig.reach[c].0 < rig.height(j) - tall / 4.0)
                .collect();
            legs.sort_by(|&a, &b| rig.reach[a].0.total_cmp(&rig.reach[b].0));
            (legs.len() >= 2).then(|| (j, spine, [legs[0], legs[1]]))
        });
        match pelvis.flatten() {
            Some(p) => found.push(p),
            None => queue.extend(kids.iter().copied()),
        }
    }
    let (pelvis, spine_start, legs) = match found[..] {
        [one] => one,
        [] => return Err("no joint branches into a spine and two legs reaching down".into()),
        _ => {
            let all: Vec<&str> = found.iter().map(|f| names[f.0].as_str()).collect();
            return Err(format!(
                "it holds {} figures (hips at {}), not one person",
                found.len(),
                all.join(", ")
            ));
        }
    };
    if rig.reach[spine_start].1 < rig.height(pelvis) + tall / 4.0 {
        return Err(format!(
            "its spine ({}) does not rise above its hips ({}): not a standing humanoid",
            names[spine_start], names[pelvis]
        ));
    }
    let mut map = vec![None; 22];
    map[PELVIS] = Some(pelvis);
    // The spine, up to the chest.
    let up = rig.follow(spine_start, |c| rig.reach[c].1);
    let Some(chest_at) = up.iter().position(|&j| rig.children[j].len() >= 3) else {
        return Err(format!(
            "no joint of its spine ({}) branches into a neck and two arms",
            names[spine_start]
        ));
    };
    let spine = &up[..=chest_at];
    let chest = spine[chest_at];
    map[SPINE[2]] = Some(chest);
    if spine.len() >= 2 {
        map[SPINE[0]] = Some(spine[0]);
    }
    if spine.len() >= 3 {
        map[SPINE[1]] = Some(spine[spine.len() / 2]);
    }
    // The neck and head: the chest's branch rising highest.
    let kids = &rig.children[chest];
    let neck = *kids
        .iter()
        .max_by(|&&a, &&b| rig.reach[a].1.total_cmp(&rig.reach[b].1))
        .expect("three children");
    let neck_chain = rig.follow(neck, |c| rig.reach[c].1);
    map[NECK] = Some(neck);
    let named_head = neck_chain[1..].iter().copied().find(|&j| {
        let lower = names[j].to_ascii_lowercase();
        lower.contains("head")
            && !["top", "end", "nub", "site"]
                .iter()
                .any(|m| lower.contains(m))
    });
    map[HEAD] = named_head.or(neck_chain.get(1).copied());
    // The arms: the chest's two longest other branches.
    let mut arms: Vec<(f64, Vec<usize>)> = kids
        .iter()
        .filter(|&&c| c != neck)
        .map(|&c| (rig.longest[c].0 + rig.bone(chest, c), rig.longest_path(c)))
        .collect();
    arms.sort_by(|a, b| b.0.total_cmp(&a.0));
    let arms: [Vec<usize>; 2] = [
        without_splits(&arms[0].1, names, points),
        without_splits(&arms[1].1, names, points),
    ];
    let leg_chains =
        legs.map(|l| without_splits(&rig.follow(l, |c| -rig.reach[c].0), names, points));
    // Facing: the way the feet point (ankle to toes, by the legs' limbs), +Z without toes.
    let mut forward = [0.0, 0.0];
    for chain in &leg_chains {
        if let Some(at) = rig.limb(chain) {
            if let (Some(&ankle), Some(&toe)) = (chain.get(at + 2), chain.get(at + 3)) {
                let (a, t) = (points[ankle], points[toe]);
                forward[0] += t[0] - a[0];
                forward[1] += t[2] - a[2];
            }
        }
    }
    let length = (forward[0] * forward[0] + forward[1] * forward[1]).sqrt();
    let forward = if length > 1e-9 {
        [forward[0] / length, forward[1] / length]
    } else {
        [0.0, 1.0]
    };
    // Left of a figure facing `forward` with Y up: up × forward.
    let left = [forward[1], -forward[0]];
    let side = |chain: &[usize]| {
        let (sum, count) = chain.iter().fold((0.0, 0.0), |(s, c), &j| {
            let d = sub(points[j], points[pelvis]);
            (s + d[0] * left[0] + d[2] * left[1], c + 1.0)
        });
        sum / count
    };
    // Which of a pair is the left one: by geometry, by the names when the geometry cannot say.
    let left_first = |a: &[usize], b: &[usize]| {
        let (ga, gb) = (side(a), side(b));
        if (ga - gb).abs() > tall * 1e-3 {
            ga > gb
        } else {
            side_named(&names[a[0]]) >= side_named(&names[b[0]])
        }
    };
    let order = |pair: [Vec<usize>; 2]| {
        let [a, b] = pair;
        if left_first(&a, &b) {
            [a, b]
        } else {
            [b, a]
        }
    };
    for (s, chain) in order(leg_chains).iter().enumerate() {
        let Some(at) = rig.limb(chain) else {
            return Err(format!(
                "its leg {} has fewer than two bones",
                names[chain[0]]
            ));
        };
        map[HIPS[s]] = Some(chain[at]);
        map[KNEES[s]] = Some(chain[at + 1]);
        map[ANKLES[s]] = chain.get(at + 2).copied();
        map[TOES[s]] = chain.get(at + 3).copied();
    }
    for (s, chain) in order(arms).iter().enumerate() {
        let Some(at) = rig.limb(chain) else {
            return Err(format!(
                "its arm {} has fewer than two bones",
                names[chain[0]]
            ));
        };
        map[COLLARS[s]] = at.checked_sub(1).map(|c| chain[c]);
        map[SHOULDERS[s]] = Some(chain[at]);
        map[ELBOWS[s]] = Some(chain[at + 1]);
        map[WRISTS[s]] = chain.get(at + 2).copied();
    }
    Ok(map)
}

/// A Z-up point turned Y up, as [`crate::motion::world::UpAxis::Z`] says: `(x, y, z) -> (x, z, -y)`.
pub(crate) fn z_up_to_y_up(p: Vec3) -> Vec3 {
    [p[0], p[2], -p[1]]
}

/// The axis a figure stands along in the pose `points` (as [`map_by_shape`] takes them): Y, the
/// BVH convention, unless the figure is a standing humanoid only when read Z up, as Blender's
/// BVH exporter writes it (armature space, unconverted). A figure that stands neither way (a
/// quadruped, a pose lying down) is left Y up: what it is, the mapping then says.
pub(crate) fn standing_axis(
    names: &[String],
    parents: &[Option<usize>],
    points: &[Vec3],
    ends: &[Option<Vec3>],
) -> UpAxis {
    if map_by_shape(names, parents, points, ends).is_ok() {
        return UpAxis::Y;
    }
    let turned: Vec<Vec3> = points.iter().map(|&p| z_up_to_y_up(p)).collect();
    let turned_ends: Vec<Option<Vec3>> = ends.iter().map(|e| e.map(z_up_to_y_up)).collect();
    if map_by_shape(names, parents, &turned, &turned_ends).is_ok() {
        UpAxis::Z
    } else {
        UpAxis::Y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A standing figure: (name, parent, position), Y up, facing +Z, its left at +X.
    fn figure(joints: &[(&str, Option<usize>, Vec3)]) -> Vec<Option<usize>> {
        let names: Vec<String> = joints.iter().map(|j| j.0.to_string()).collect();
        let parents: Vec<Option<usize>> = joints.iter().map(|j| j.1).collect();
        let points: Vec<Vec3> = joints.iter().map(|j| j.2).collect();
        map_by_shape(&names, &parents, &points, &vec![None; points.len()]).unwrap()
    }

    /// Names that say nothing, a collar on each arm, two spine joints, no toes, in an order no
    /// exporter uses (right before left).
    fn standing() -> Vec<(&'static str, Option<usize>, Vec3)> {
        vec![
            ("a", None, [0.0, 1.0, 0.0]),        // 0 pelvis
            ("b", Some(0), [-0.1, 0.95, 0.0]),   // 1 right hip
            ("c", Some(1), [-0.1, 0.5, 0.0]),    // 2 right knee
            ("d", Some(2), [-0.1, 0.08, 0.0]),   // 3 right ankle
            ("e", Some(0), [0.1, 0.95, 0.0]),    // 4 left hip
            ("f", Some(4), [0.1, 0.5, 0.0]),     // 5 left knee
            ("g", Some(5), [0.1, 0.08, 0.0]),    // 6 left ankle
            ("h", Some(0), [0.0, 1.2, 0.0]),     // 7 spine
            ("i", Some(7), [0.0, 1.4, 0.0]),     // 8 chest
            ("j", Some(8), [0.0, 1.55, 0.0]),    // 9 neck
            ("k", Some(9), [0.0, 1.65, 0.0]),    // 10 head
            ("l", Some(8), [-0.05, 1.45, 0.0]),  // 11 right collar
            ("m", Some(11), [-0.18, 1.45, 0.0]), // 12 right shoulder
            ("n", Some(12), [-0.45, 1.45, 0.0]), // 13 right elbow
            ("o", Some(13), [-0.7, 1.45, 0.0]),  // 14 right wrist
            ("p", Some(8), [0.05, 1.45, 0.0]),   // 15 left collar
            ("q", Some(15), [0.18, 1.45, 0.0]),  // 16 left shoulder
            ("r", Some(16), [0.45, 1.45, 0.0]),  // 17 left elbow
            ("s", Some(17), [0.7, 1.45, 0.0]),   // 18 left wrist
        ]
    }

    #[test]
    fn a_rig_named_in_no_known_way_is_mapped_by_its_shape() {
        let map = figure(&standing());
        let want = [
            (PELVIS, Some(0)),
            (HIPS[0], Some(4)),
            (HIPS[1], Some(1)),
            (KNEES[0], Some(5)),
            (ANKLES[1], Some(3)),
            (TOES[0], None),
            (SPINE[0], Some(7)),
            (SPINE[1], None),
            (SPINE[2], Some(8)),
            (NECK, Some(9)),
            (HEAD, Some(10)),
            (COLLARS[0], Some(15)),
            (SHOULDERS[0], Some(16)),
            (ELBOWS[1], Some(13)),
            (WRISTS[0], Some(18)),
        ];
        for (joint, rig) in want {
            assert_eq!(map[joint], rig, "t2m joint {joint}");
        }
    }

    #[test]
    fn shapes_that_are_not_standing_humanoids_are_refused_with_the_reason() {
        let names: Vec<String> = (0..4).map(|i| format!("j{i}")).collect();
        let chain = map_by_shape(
            &names,
            &[None, Some(0), Some(1), Some(2)],
            &[
                [0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.0, 3.0, 0.0],
            ],
            &[None; 4],
        );
        assert!(chain.unwrap_err().contains("no joint branches"));
        // A four-legged figure: hind legs down from the hips, the spine level with them.
        let names: Vec<String> = (0..9).map(|i| format!("j{i}")).collect();
        let dog = map_by_shape(
            &names,
            &[
                None,
                Some(0),
                Some(1),
                Some(0),
                Some(3),
                Some(0),
                Some(5),
                Some(6),
                Some(7),
            ],
            &[
                [0.0, 0.6, 0.0],
                [0.1, 0.3, 0.0],
                [0.1, 0.0, 0.0],
                [-0.1, 0.3, 0.0],
                [-0.1, 0.0, 0.0],
                [0.0, 0.6, 0.3],
                [0.0, 0.62, 0.6],
                [0.0, 0.65, 0.8],
                [0.0, 0.7, 0.9],
            ],
            &[None; 9],
        );
        assert!(dog.unwrap_err().contains("does not rise above its hips"));
        // Two people under one root (a scene): which one is meant is not for troupe to guess.
        let one = standing();
        let mut names = vec!["scene".to_string()];
        let mut parents = vec![None];
        let mut points = vec![[0.0, 0.0, 0.0]];
        for shift in [0.0, 2.0] {
            let first = names.len();
            for (name, parent, p) in &one {
                names.push(format!("{name}{shift}"));
                parents.push(Some(parent.map_or(0, |q| q + first)));
                points.push([p[0] + shift, p[1], p[2]]);
            }
        }
        let two = map_by_shape(&names, &parents, &points, &vec![None; points.len()]).unwrap_err();
        assert!(two.contains("holds 2 figures"), "{two}");
    }
}
