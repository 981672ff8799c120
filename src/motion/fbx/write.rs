//! The FBX writer for a caller's rig: its hierarchy and rest pose, and poses retargeted onto it,
//! as binary FBX 7.4, the version Blender, Unity, Unreal, Maya and MotionBuilder all read.
//!
//! The node records are written by `fbxcel` (MIT/Apache-2.0), a maintained reader and writer of
//! FBX's binary node tree (header, record offsets, array encodings, footer); what the nodes say
//! (the scene's settings, the skeleton as `LimbNode` models, the animation as curves, and the
//! connections between them) is troupe's, following what Blender's and Autodesk's exporters
//! write. ASCII FBX is not written: Blender does not import it.
//!
//! What is in the file:
//! - `GlobalSettings`: Y up, right-handed (FBX's own axes), the unit asked for
//!   (`UnitScaleFactor`: centimetres per unit), a custom frame rate of the clip's.
//! - One `LimbNode` model per joint, its rest translation and rotation (Euler XYZ, FBX's default
//!   order: `R = Rz · Ry · Rx`) as its static transform, and a `<joint>_end` leaf where the rig
//!   has an end site (as Blender's exporter adds them; troupe's reader reads them back as end
//!   sites). No bind pose: there is no mesh.
//! - One animation stack: every joint's rotation and the moving joint's translation, one key per
//!   frame (linear), each Euler channel unwrapped so that consecutive keys differ by less than
//!   180 degrees.

use std::io::Cursor;

use fbxcel::low::FbxVersion;
use fbxcel::writer::v7400::binary::{FbxFooter, Writer};

use crate::motion::bvh::euler_zyx_degrees;
use crate::motion::rig::{Rig, RigPose};
use crate::motion::rotation::Quat;
use crate::motion::vec3::Vec3;
use crate::motion::world::{JointsFormat, Units};
use crate::shared::error::{excerpt, Error, Result};

/// FBX time units per second.
const KTIME_PER_SECOND: i64 = 46_186_158_000;

/// The largest coordinate written (file units), as the BVH writer's.
const MAX_FBX_COORDINATE: f64 = 1e6;

/// How [`write_rig_fbx`] writes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FbxWriteOptions {
    /// The file's length unit; centimetres, FBX's own, by default.
    pub units: Units,
    /// Frames per second of the poses.
    pub fps: f32,
}

impl Default for FbxWriteOptions {
    fn default() -> Self {
        FbxWriteOptions {
            units: Units::Centimeters,
            fps: 30.0,
        }
    }
}

/// The bytes of a binary FBX file of `rig` posed by `poses` (at least one, each with one
/// rotation per joint and the same moving joint).
pub fn write_rig_fbx(rig: &Rig, poses: &[RigPose], options: &FbxWriteOptions) -> Result<Vec<u8>> {
    let bad =
        |m: String| Error::InvalidInput(format!("FBX out on rig {}: {m}", excerpt(rig.name())));
    let moving = rig.check_poses(poses, options.fps, "FBX")?;
    // FBX joins an object's name and class with the bytes 0 and 1: a name may hold neither.
    if let Some(name) = rig.names().iter().find(|n| n.contains(['\0', '\u{1}'])) {
        return Err(bad(format!(
            "joint `{}`: FBX names cannot hold the bytes 0 or 1",
            excerpt(name)
        )));
    }
    let format = JointsFormat {
        units: options.units,
        ..JointsFormat::default()
    };
    let out_rig = rig.with_format(format);
    let translation = |pose: &RigPose| {
        format.point_from_canonical(rig.format().point_to_canonical(pose.root_translation))
    };
    let far = |v: &Vec3| v.iter().any(|c| c.abs() > MAX_FBX_COORDINATE);
    let ends = out_rig.end_sites().iter().flatten();
    if out_rig.offsets().iter().chain(ends).any(far) || poses.iter().any(|p| far(&translation(p))) {
        return Err(bad(format!(
            "a bone or the root beyond ±{MAX_FBX_COORDINATE} file units"
        )));
    }
    let rotations: Vec<Vec<[f64; 3]>> = (0..rig.len())
        .map(|j| {
            unwrapped(poses.iter().map(|pose| {
                xyz_degrees(format.rotation_from_canonical_axes(
                    rig.format().rotation_to_canonical_axes(pose.rotations[j]),
                ))
            }))
        })
        .collect();
    let moves: Vec<Vec3> = poses.iter().map(translation).collect();
    let document = Document {
        rig: &out_rig,
        options,
        frames: poses.len(),
        rotations: &rotations,
        moving,
        moves: &moves,
    };
    document
        .write()
        .map_err(|e| bad(format!("the writer refused: {e}")))
}

/// [`write_rig_fbx`] into the file at `path`, atomically.
pub fn write_rig_fbx_file(
    path: &std::path::Path,
    rig: &Rig,
    poses: &[RigPose],
    options: &FbxWriteOptions,
) -> Result<()> {
    let bytes = write_rig_fbx(rig, poses, options)?;
    crate::shared::files::write_atomically(path, &bytes)
}

/// Euler angles in degrees, `[x, y, z]` with `R = Rz(z) · Ry(y) · Rx(x)` (FBX's `eEulerXYZ`).
fn xyz_degrees(q: Quat) -> [f64; 3] {
    let [z, y, x] = euler_zyx_degrees(q);
    [x, y, z]
}

/// Each channel moved by whole turns to within 180 degrees of the frame before: the same
/// rotations, without the jumps that would make the curves spin between keys.
fn unwrapped(frames: impl Iterator<Item = [f64; 3]>) -> Vec<[f64; 3]> {
    let mut out: Vec<[f64; 3]> = Vec::new();
    for mut angles in frames {
        if let Some(last) = out.last() {
            for (a, l) in angles.iter_mut().zip(last) {
                *a += 360.0 * ((l - *a) / 360.0).round();
            }
        }
        out.push(angles);
    }
    out
}

/// Object ids: each object's own, from 1 up (0 is the scene's root).
struct Ids(i64);

impl Ids {
    fn next(&mut self) -> i64 {
        self.0 += 1;
        self.0
    }
}

/// What one file holds, already in the file's units and axes.
struct Document<'a> {
    rig: &'a Rig,
    options: &'a FbxWriteOptions,
    frames: usize,
    /// Per joint, per frame: Euler XYZ degrees.
    rotations: &'a [Vec<[f64; 3]>],
    moving: usize,
    /// Per frame: the moving joint's translation.
    moves: &'a [Vec3],
}

type Fbx = Writer<Cursor<Vec<u8>>>;
type WriteResult<T> = std::result::Result<T, fbxcel::writer::v7400::binary::Error>;

impl Document<'_> {
    fn write(&self) -> WriteResult<Vec<u8>> {
        let mut w = Writer::new(Cursor::new(Vec::new()), FbxVersion::V7_4)?;
        self.header(&mut w)?;
        self.settings(&mut w)?;
        let mut connections: Vec<(&'static str, i64, i64, Option<String>)> = Vec::new();
        let mut ids = Ids(0);
        let models = self.rig.len() + self.rig.end_sites().iter().flatten().count();
        let curve_nodes = self.rig.len() + 1;
        self.definitions(&mut w, models, curve_nodes)?;
        w.new_node("Objects")?;
        // The skeleton: a model and its attribute per joint, and the end-site leaves.
        let mut model_ids = Vec::with_capacity(self.rig.len());
        for j in 0..self.rig.len() {
            let (t, r) = (self.rig.offsets()[j], self.rest_rotation(j));
            let id = limb(
                &mut w,
                &mut ids,
                &self.rig.names()[j],
                t,
                r,
                &mut connections,
            )?;
            let parent = self.rig.parents()[j].map_or(0, |p| model_ids[p]);
            connections.push(("OO", id, parent, None));
            model_ids.push(id);
        }
        for (j, end) in self.rig.end_sites().iter().enumerate() {
            if let Some(end) = end {
                let name = format!("{}_end", self.rig.names()[j]);
                let id = limb(&mut w, &mut ids, &name, *end, [0.0; 3], &mut connections)?;
                connections.push(("OO", id, model_ids[j], None));
            }
        }
        // The animation: a stack, a layer, and a curve node per animated property.
        let stop = self.ktime(self.frames - 1);
        let stack = ids.next();
        {
            let mut a = w.new_node("AnimationStack")?;
            a.append_i64(stack)?;
            a.append_string_direct("Take 001\u{0}\u{1}AnimStack")?;
            a.append_string_direct("")?;
        }
        properties(&mut w, |w| {
            for name in ["LocalStart", "ReferenceStart"] {
                property_ktime(w, name, 0)?;
            }
            for name in ["LocalStop", "ReferenceStop"] {
                property_ktime(w, name, stop)?;
            }
            Ok(())
        })?;
        w.close_node()?;
        let layer = ids.next();
        {
            let mut a = w.new_node("AnimationLayer")?;
            a.append_i64(layer)?;
            a.append_string_direct("BaseLayer\u{0}\u{1}AnimLayer")?;
            a.append_string_direct("")?;
        }
        w.close_node()?;
        connections.push(("OO", layer, stack, None));
        for (j, &model) in model_ids.iter().enumerate() {
            let curves = self.rotations[j].clone();
            self.animate(
                &mut w,
                &mut ids,
                &mut connections,
                (model, layer),
                "R",
                &curves,
            )?;
        }
        let moves: Vec<[f64; 3]> = self.moves.to_vec();
        let moving = (model_ids[self.moving], layer);
        self.animate(&mut w, &mut ids, &mut connections, moving, "T", &moves)?;
        w.close_node()?; // Objects
        w.new_node("Connections")?;
        for (kind, child, parent, property) in &connections {
            {
                let mut a = w.new_node("C")?;
                a.append_string_direct(kind)?;
                a.append_i64(*child)?;
                a.append_i64(*parent)?;
                if let Some(p) = property {
                    a.append_string_direct(p)?;
                }
            }
            w.close_node()?;
        }
        w.close_node()?;
        Ok(w.finalize(&FbxFooter::default())?.into_inner())
    }

    fn rest_rotation(&self, j: usize) -> [f64; 3] {
        xyz_degrees(self.rig.rest_rotations()[j])
    }

    fn ktime(&self, frame: usize) -> i64 {
        (frame as f64 * KTIME_PER_SECOND as f64 / f64::from(self.options.fps)).round() as i64
    }

    fn header(&self, w: &mut Fbx) -> WriteResult<()> {
        w.new_node("FBXHeaderExtension")?;
        w.new_node("FBXHeaderVersion")?.append_i32(1003)?;
        w.close_node()?;
        w.new_node("FBXVersion")?.append_i32(7400)?;
        w.close_node()?;
        w.new_node("Creator")?
            .append_string_direct(concat!("troupe ", env!("CARGO_PKG_VERSION")))?;
        w.close_node()?;
        w.close_node()
    }

    fn settings(&self, w: &mut Fbx) -> WriteResult<()> {
        let centimetres = self.options.units.meters() * 100.0;
        w.new_node("GlobalSettings")?;
        w.new_node("Version")?.append_i32(1000)?;
        w.close_node()?;
        properties(w, |w| {
            for (name, value) in [
                ("UpAxis", 1),
                ("UpAxisSign", 1),
                ("FrontAxis", 2),
                ("FrontAxisSign", 1),
                ("CoordAxis", 0),
                ("CoordAxisSign", 1),
                ("OriginalUpAxis", 1),
                ("OriginalUpAxisSign", 1),
            ] {
                property(w, name, "int", "Integer", "", |a| a.append_i32(value))?;
            }
            for name in ["UnitScaleFactor", "OriginalUnitScaleFactor"] {
                property(w, name, "double", "Number", "", |a| {
                    a.append_f64(centimetres)
                })?;
            }
            // eCustom: the rate is `CustomFrameRate`.
            property(w, "TimeMode", "enum", "", "", |a| a.append_i32(14))?;
            property(w, "CustomFrameRate", "double", "Number", "", |a| {
                a.append_f64(f64::from(self.options.fps))
            })?;
            property_ktime(w, "TimeSpanStart", 0)?;
            property_ktime(w, "TimeSpanStop", self.ktime(self.frames - 1))
        })?;
        w.close_node()
    }

    fn definitions(&self, w: &mut Fbx, models: usize, curve_nodes: usize) -> WriteResult<()> {
        let counts = [
            ("GlobalSettings", 1),
            ("Model", models),
            ("NodeAttribute", models),
            ("AnimationStack", 1),
            ("AnimationLayer", 1),
            ("AnimationCurveNode", curve_nodes),
            ("AnimationCurve", curve_nodes * 3),
        ];
        w.new_node("Definitions")?;
        w.new_node("Version")?.append_i32(100)?;
        w.close_node()?;
        w.new_node("Count")?
            .append_i32(counts.iter().map(|c| c.1 as i32).sum())?;
        w.close_node()?;
        for (kind, count) in counts {
            w.new_node("ObjectType")?.append_string_direct(kind)?;
            w.new_node("Count")?.append_i32(count as i32)?;
            w.close_node()?;
            w.close_node()?;
        }
        w.close_node()
    }

    /// A curve node for `what` ("R": `Lcl Rotation`, "T": `Lcl Translation`) of `model`, with
    /// one curve per axis holding `values` (per frame, x y z).
    fn animate(
        &self,
        w: &mut Fbx,
        ids: &mut Ids,
        connections: &mut Vec<(&'static str, i64, i64, Option<String>)>,
        (model, layer): (i64, i64),
        what: &str,
        values: &[[f64; 3]],
    ) -> WriteResult<()> {
        let property_name = if what == "R" {
            "Lcl Rotation"
        } else {
            "Lcl Translation"
        };
        let node = ids.next();
        {
            let mut a = w.new_node("AnimationCurveNode")?;
            a.append_i64(node)?;
            a.append_string_direct(&format!("{what}\u{0}\u{1}AnimCurveNode"))?;
            a.append_string_direct("")?;
        }
        properties(w, |w| {
            for (d, axis) in ["d|X", "d|Y", "d|Z"].iter().enumerate() {
                property(w, axis, "Number", "", "A", |a| a.append_f64(values[0][d]))?;
            }
            Ok(())
        })?;
        w.close_node()?;
        connections.push(("OO", node, layer, None));
        connections.push(("OP", node, model, Some(property_name.to_string())));
        let times: Vec<i64> = (0..self.frames).map(|t| self.ktime(t)).collect();
        for (d, axis) in ["d|X", "d|Y", "d|Z"].iter().enumerate() {
            let curve = ids.next();
            {
                let mut a = w.new_node("AnimationCurve")?;
                a.append_i64(curve)?;
                a.append_string_direct("\u{0}\u{1}AnimCurve")?;
                a.append_string_direct("")?;
            }
            w.new_node("Default")?.append_f64(values[0][d])?;
            w.close_node()?;
            w.new_node("KeyVer")?.append_i32(4009)?;
            w.close_node()?;
            w.new_node("KeyTime")?
                .append_arr_i64_from_iter(None, times.iter().copied())?;
            w.close_node()?;
            w.new_node("KeyValueFloat")?
                .append_arr_f32_from_iter(None, values.iter().map(|v| v[d] as f32))?;
            w.close_node()?;
            // One attribute set for every key: linear interpolation (eInterpolationLinear).
            w.new_node("KeyAttrFlags")?
                .append_arr_i32_from_iter(None, [4])?;
            w.close_node()?;
            w.new_node("KeyAttrDataFloat")?
                .append_arr_f32_from_iter(None, [0.0; 4])?;
            w.close_node()?;
            w.new_node("KeyAttrRefCount")?
                .append_arr_i32_from_iter(None, [self.frames as i32])?;
            w.close_node()?;
            w.close_node()?;
            connections.push(("OP", curve, node, Some((*axis).to_string())));
        }
        Ok(())
    }
}

/// A `LimbNode` model (and its node attribute) with a static transform; returns its id.
fn limb(
    w: &mut Fbx,
    ids: &mut Ids,
    name: &str,
    translation: Vec3,
    rotation: [f64; 3],
    connections: &mut Vec<(&'static str, i64, i64, Option<String>)>,
) -> WriteResult<i64> {
    let attribute = ids.next();
    {
        let mut a = w.new_node("NodeAttribute")?;
        a.append_i64(attribute)?;
        a.append_string_direct(&format!("{name}\u{0}\u{1}NodeAttribute"))?;
        a.append_string_direct("LimbNode")?;
    }
    w.new_node("TypeFlags")?.append_string_direct("Skeleton")?;
    w.close_node()?;
    w.close_node()?;
    let model = ids.next();
    {
        let mut a = w.new_node("Model")?;
        a.append_i64(model)?;
        a.append_string_direct(&format!("{name}\u{0}\u{1}Model"))?;
        a.append_string_direct("LimbNode")?;
    }
    w.new_node("Version")?.append_i32(232)?;
    w.close_node()?;
    properties(w, |w| {
        let vector = |w: &mut Fbx, name: &str, v: [f64; 3]| {
            property(w, name, name, "", "A", |a| {
                a.append_f64(v[0])?;
                a.append_f64(v[1])?;
                a.append_f64(v[2])
            })
        };
        vector(w, "Lcl Translation", translation)?;
        vector(w, "Lcl Rotation", rotation)?;
        vector(w, "Lcl Scaling", [1.0; 3])
    })?;
    w.close_node()?;
    connections.push(("OO", attribute, model, None));
    Ok(model)
}

/// A `Properties70` node whose children `body` writes.
fn properties(w: &mut Fbx, body: impl FnOnce(&mut Fbx) -> WriteResult<()>) -> WriteResult<()> {
    w.new_node("Properties70")?;
    body(w)?;
    w.close_node()
}

type Attributes<'a> = fbxcel::writer::v7400::binary::AttributesWriter<'a, Cursor<Vec<u8>>>;

/// One `P` record: name, type, label, flags, then the values `values` appends.
fn property(
    w: &mut Fbx,
    name: &str,
    kind: &str,
    label: &str,
    flags: &str,
    values: impl FnOnce(&mut Attributes) -> WriteResult<()>,
) -> WriteResult<()> {
    {
        let mut a = w.new_node("P")?;
        for s in [name, kind, label, flags] {
            a.append_string_direct(s)?;
        }
        values(&mut a)?;
    }
    w.close_node()
}

fn property_ktime(w: &mut Fbx, name: &str, time: i64) -> WriteResult<()> {
    property(w, name, "KTime", "Time", "", |a| a.append_i64(time))
}
