//! Which joint of a motion-capture rig each t2m-22 joint is: a name map a user can extend
//! (`rigs/t2m22-joint-names.json` beside this file is the built-in one).

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::motion::skeleton::Skeleton;
use crate::shared::error::{Error, Result};

/// The built-in map's JSON document.
pub const T2M22_JOINT_NAMES_JSON: &str = include_str!("rigs/t2m22-joint-names.json");

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MapDoc {
    #[serde(default)]
    #[allow(dead_code)]
    about: String,
    skeleton: String,
    joints: BTreeMap<String, Vec<String>>,
}

/// For each t2m-22 joint, the rig joint names it may go by, tried in order.
#[derive(Debug, Clone, PartialEq)]
pub struct JointMap {
    /// Candidates per t2m-22 joint, in skeleton order.
    candidates: Vec<Vec<String>>,
}

/// A rig name without its namespace (`mixamorig:Hips` → `Hips`).
fn bare(name: &str) -> &str {
    name.rsplit(':').next().unwrap_or(name)
}

impl JointMap {
    /// The built-in map (LAFAN1, Mixamo, CMU, HumanIK and SMPL names).
    pub fn builtin() -> JointMap {
        JointMap::from_json(T2M22_JOINT_NAMES_JSON).expect("the built-in map is valid (tested)")
    }

    /// A map from its JSON document: `{"skeleton": "t2m22", "joints": {"pelvis": ["Hips", ...],
    /// ...}}` with an entry for every t2m-22 joint; an empty list says the rig has no such joint
    /// (placed from its neighbours where troupe can: `docs/RIGS.md`).
    pub fn from_json(text: &str) -> Result<JointMap> {
        let bad = |m: String| Error::InvalidInput(format!("joint map: {m}"));
        let doc: MapDoc = serde_json::from_str(text).map_err(|e| {
            // A file name where the text was meant is the usual mistake: say what is expected.
            let hint = if text.trim_start().starts_with('{') {
                ""
            } else {
                " (a joint map is JSON text, {\"skeleton\": \"t2m22\", \"joints\": {...}}, \
                 not the name of a file)"
            };
            bad(format!("not a joint map: {e}{hint}"))
        })?;
        let skeleton = Skeleton::t2m22();
        if doc.skeleton != skeleton.name() {
            return Err(bad(format!(
                "maps to skeleton {:?}; troupe maps to {:?}",
                doc.skeleton,
                skeleton.name()
            )));
        }
        if let Some(unknown) = doc.joints.keys().find(|k| skeleton.index_of(k).is_none()) {
            return Err(bad(format!("{unknown:?} is not a t2m-22 joint")));
        }
        let candidates = skeleton
            .names()
            .iter()
            .map(|n| {
                // An empty list says the rig has no such joint: it is placed from its
                // neighbours where troupe can (`joint_inference`), else the rig is refused.
                doc.joints.get(n).cloned().ok_or_else(|| {
                    bad(format!(
                        "no entry for t2m-22 joint {n:?} (list its names on your rig, or [] \
                         if the rig has no such joint)"
                    ))
                })
            })
            .collect::<Result<_>>()?;
        Ok(JointMap { candidates })
    }

    /// This map with `names` tried first for t2m-22 joint `joint` (e.g. your rig's name for it).
    pub fn with_names(mut self, joint: &str, names: &[&str]) -> Result<JointMap> {
        let j = Skeleton::t2m22().index_of(joint).ok_or_else(|| {
            Error::InvalidInput(format!("joint map: {joint:?} is not a t2m-22 joint"))
        })?;
        let mut first: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        first.append(&mut self.candidates[j]);
        self.candidates[j] = first;
        Ok(self)
    }

    /// For each t2m-22 joint, the index of its joint among `rig` (a rig's joint names), or
    /// `None` where the rig has no joint of any of its names. A name matching with its case
    /// wins over one matching without (LAFAN1's `Spine1` is t2m's `spine2`, not its `spine1`),
    /// and no rig joint is taken twice.
    pub fn resolve_partial(&self, rig: &[String]) -> Vec<Option<usize>> {
        let mut taken = vec![false; rig.len()];
        let mut out = vec![None; self.candidates.len()];
        // Exact matches for every joint first, then the rest without regard to case.
        type Same = fn(&str, &str) -> bool;
        let passes: [Same; 2] = [|a, b| a == b, |a, b| a.eq_ignore_ascii_case(b)];
        for same in passes {
            for (j, candidates) in self.candidates.iter().enumerate() {
                if out[j].is_some() {
                    continue;
                }
                let hit = candidates.iter().find_map(|c| {
                    (0..rig.len()).find(|&i| !taken[i] && same(bare(&rig[i]), bare(c)))
                });
                if let Some(i) = hit {
                    taken[i] = true;
                    out[j] = Some(i);
                }
            }
        }
        out
    }

    /// For each t2m-22 joint, the index of its joint among `rig` (a rig's joint names), or an
    /// error naming every t2m-22 joint the rig lacks and the names that were tried (`label`
    /// names the rig, e.g. its file).
    pub fn resolve(&self, rig: &[String], label: &str) -> Result<Vec<usize>> {
        let names = Skeleton::t2m22().names().to_vec();
        let found = self.resolve_partial(rig);
        let missing: Vec<String> = found
            .iter()
            .enumerate()
            .filter(|(_, f)| f.is_none())
            .map(|(j, _)| match &self.candidates[j][..] {
                [] => format!("{} (the joint map says the rig has none)", names[j]),
                tried => format!("{} (tried {})", names[j], tried.join(", ")),
            })
            .collect();
        if !missing.is_empty() {
            return Err(Error::InvalidInput(format!(
                "{label}: no joint of this rig is the t2m-22 joint {}; extend the joint map with \
                 your rig's names",
                missing.join("; ")
            )));
        }
        Ok(found.into_iter().flatten().collect())
    }

    /// The names tried for t2m-22 joint `joint` (its index), in order.
    pub fn names_for(&self, joint: usize) -> &[String] {
        &self.candidates[joint]
    }
}
