//! glTF 2.0 binary files (`.glb`): rigs posed by troupe, as engines and DCC tools import them.
//!
//! Each person is a skeleton of nodes (the rig's joints with their rest translations and
//! rotations), a skin over it (also without a body: importers make armatures of skins; the
//! validator then notes the skin as possibly unused, an information, not a warning), and, so
//! that a viewer shows a body, a capsule per bone skinned rigidly to the bone's joint; one
//! animation holds every person's channels (each joint's rotation, the root joint's
//! translation), sampled linearly at the clip's frame rate. The document is built with
//! `gltf-json`'s types; this module only frames it as GLB (a 12-byte header and two chunks,
//! glTF 2.0 §4.4). [`read_gltf_rig`] reads a rig back from any glTF file's skin.
//!
//! Axes are glTF's, which are troupe's canonical ones: metres, +Y up, right-handed; a rig in
//! other units or axes is converted (its shape does not change).

use std::collections::BTreeMap;
use std::path::Path;

use gltf_json as json;
use json::validation::{Checked, USize64};

use crate::motion::rig::{Rig, RigPose};
use crate::motion::rotation::Quat;
use crate::motion::vec3::{add, cross, norm, normalize, scale, sub, Vec3};
use crate::motion::world::{JointsFormat, FPS_RANGE};
use crate::shared::error::{excerpt, Error, Result};

/// One person to write: a rig and its poses, one per frame.
#[derive(Debug, Clone, Copy)]
pub struct GltfPerson<'a> {
    /// The person's name (node names are prefixed with it when a file holds several people).
    pub name: &'a str,
    /// The rig the poses are on.
    pub rig: &'a Rig,
    /// One pose per frame.
    pub poses: &'a [RigPose],
    /// The body's colour, linear RGB in [0, 1].
    pub color: [f32; 3],
}

/// How to write a glTF file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GltfOptions {
    /// Frames per second of the poses.
    pub fps: f32,
    /// Add a skinned capsule body per person (without one, viewers show only empty nodes).
    pub bodies: bool,
}

impl Default for GltfOptions {
    fn default() -> Self {
        GltfOptions {
            fps: 30.0,
            bodies: true,
        }
    }
}

/// The colours troupe gives people by default: the viewer's actor blue and reactor orange,
/// then more.
pub const PERSON_COLORS: [[f32; 3]; 4] = [
    [0.12, 0.35, 0.85],
    [0.92, 0.42, 0.08],
    [0.15, 0.65, 0.25],
    [0.65, 0.2, 0.7],
];

/// Longitude steps and latitude rings per hemisphere of a capsule.
const CAPSULE_SEGMENTS: usize = 12;
const CAPSULE_RINGS: usize = 4;

/// Bytes written into the binary chunk, with the views and accessors that describe them.
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
}

impl Builder {
    /// A buffer view over `bytes` (aligned to 4), with an optional vertex/index target.
    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Checked::Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    /// An accessor over a new view of `bytes`.
    #[allow(clippy::too_many_arguments)]
    fn accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        component: json::accessor::ComponentType,
        kind: json::accessor::Type,
        target: Option<json::buffer::Target>,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        let view = self.view(bytes, target);
        let (min, max) = match bounds {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Checked::Valid(kind),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A float accessor of `width`-wide elements, with bounds when `bounded`.
    fn floats(
        &mut self,
        values: &[f32],
        width: usize,
        target: Option<json::buffer::Target>,
        bounded: bool,
    ) -> json::Index<json::Accessor> {
        let kind = match width {
            1 => json::accessor::Type::Scalar,
            3 => json::accessor::Type::Vec3,
            4 => json::accessor::Type::Vec4,
            _ => json::accessor::Type::Mat4,
        };
        let bounds = bounded.then(|| {
            let mut lo = vec![f32::INFINITY; width];
            let mut hi = vec![f32::NEG_INFINITY; width];
            for chunk in values.chunks(width) {
                for (i, v) in chunk.iter().enumerate() {
                    lo[i] = lo[i].min(*v);
                    hi[i] = hi[i].max(*v);
                }
            }
            (lo, hi)
        });
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.accessor(
            &bytes,
            values.len() / width,
            json::accessor::ComponentType::F32,
            kind,
            target,
            bounds,
        )
    }
}

/// The capsule around segment `a`→`b` of radius `r`: positions, normals, and triangles
/// (counter-clockwise seen from outside), indices starting at `base`.
fn capsule(a: Vec3, b: Vec3, r: f64, base: u32) -> (Vec<Vec3>, Vec<Vec3>, Vec<u32>) {
    let u = normalize(sub(b, a)).unwrap_or([0.0, 1.0, 0.0]);
    let helper = if u[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let v = normalize(cross(helper, u)).expect("helper is not parallel to u");
    let w = cross(u, v);
    let (s, rings) = (CAPSULE_SEGMENTS, CAPSULE_RINGS);
    let mut pos = Vec::new();
    let mut nor = Vec::new();
    let mut push = |centre: Vec3, lat: f64, lon: f64| {
        let (sl, cl) = lat.sin_cos();
        let (so, co) = lon.sin_cos();
        let n = add(scale(add(scale(v, co), scale(w, so)), cl), scale(u, sl));
        pos.push(add(centre, scale(n, r)));
        nor.push(n);
    };
    let half = std::f64::consts::FRAC_PI_2;
    push(a, -half, 0.0);
    // Rings from the bottom hemisphere's first to the equator at `a`, then `b`'s equator up.
    let mut ring_count = 0;
    for i in 1..=rings {
        let lat = -half + half * i as f64 / rings as f64;
        for j in 0..s {
            push(a, lat, std::f64::consts::TAU * j as f64 / s as f64);
        }
        ring_count += 1;
    }
    for i in 0..rings {
        let lat = half * i as f64 / rings as f64;
        for j in 0..s {
            push(b, lat, std::f64::consts::TAU * j as f64 / s as f64);
        }
        ring_count += 1;
    }
    push(b, half, 0.0);
    let ring = |i: usize, j: usize| base + 1 + (i * s + j % s) as u32;
    let top = base + 1 + (ring_count * s) as u32;
    let mut idx = Vec::new();
    for j in 0..s {
        idx.extend([base, ring(0, j + 1), ring(0, j)]);
    }
    for i in 0..ring_count - 1 {
        for j in 0..s {
            idx.extend([ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)]);
            idx.extend([ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)]);
        }
    }
    for j in 0..s {
        idx.extend([ring(ring_count - 1, j), ring(ring_count - 1, j + 1), top]);
    }
    (pos, nor, idx)
}

/// The radius of the capsule over a bone of `length` metres.
fn capsule_radius(length: f64) -> f64 {
    (0.14 * length).clamp(0.025, 0.06)
}

/// A linearly interpolated animation sampler of `output` keyed at the times `input`.
fn linear(
    input: json::Index<json::Accessor>,
    output: json::Index<json::Accessor>,
) -> json::animation::Sampler {
    json::animation::Sampler {
        input,
        interpolation: Checked::Valid(json::animation::Interpolation::Linear),
        output,
        extensions: None,
        extras: Default::default(),
    }
}

fn f32s(v: Vec3) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// Column-major 4×4 of the inverse of the rigid transform (rotation `q`, then translation
/// `t`).
fn inverse_bind(q: Quat, t: Vec3) -> [f32; 16] {
    let r = q.conj().to_matrix();
    let ti = r.map(|row| -(row[0] * t[0] + row[1] * t[1] + row[2] * t[2]));
    let mut m = [0.0f32; 16];
    for col in 0..3 {
        for row in 0..3 {
            m[col * 4 + row] = r[row][col] as f32;
        }
    }
    for row in 0..3 {
        m[12 + row] = ti[row] as f32;
    }
    m[15] = 1.0;
    m
}

/// The bytes of a `.glb` file holding `people` (at least one, each with at least one frame).
/// People may have different numbers of frames: each person's animation keys are its own, and a
/// shorter one holds its last pose to the end of the longest, as every glTF client holds a
/// sampler past its last key (no trimming, no padding).
pub fn write_glb(people: &[GltfPerson], options: &GltfOptions) -> Result<Vec<u8>> {
    let bad = |m: String| Error::InvalidInput(format!("glTF out: {m}"));
    if people.is_empty() {
        return Err(bad("no people to write".into()));
    }
    if !FPS_RANGE.contains(&options.fps) {
        return Err(bad(format!("{} fps is outside [1, 1000]", options.fps)));
    }
    for (k, p) in people.iter().enumerate() {
        if p.poses.is_empty() {
            return Err(bad(format!("{}: a clip of 0 frames", excerpt(p.name))));
        }
        if p.name.is_empty() || p.name.chars().any(char::is_control) {
            return Err(bad(format!(
                "person {k}: a name without control characters"
            )));
        }
        if p.color.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(bad(format!(
                "{}: colour components are in [0, 1]",
                excerpt(p.name)
            )));
        }
        for (t, pose) in p.poses.iter().enumerate() {
            let finite = pose
                .rotations
                .iter()
                .all(|q| [q.w, q.x, q.y, q.z].iter().all(|v| v.is_finite()))
                && pose.root_translation.iter().all(|v| v.is_finite());
            if pose.rotations.len() != p.rig.len()
                || pose.root != p.poses[0].root
                || pose.root >= p.rig.len()
                || !finite
            {
                return Err(bad(format!(
                    "{}, frame {t}: a pose needs {} finite rotations and the same root joint of the rig",
                    excerpt(p.name),
                    p.rig.len()
                )));
            }
        }
    }
    let mut b = Builder {
        root: json::Root {
            asset: json::Asset {
                generator: Some(format!("troupe {}", env!("CARGO_PKG_VERSION"))),
                ..Default::default()
            },
            ..Default::default()
        },
        bin: Vec::new(),
    };
    // One key time accessor per length the people have (with its min and max, as glTF asks).
    let mut time_accessors = std::collections::BTreeMap::new();
    for p in people {
        time_accessors.entry(p.poses.len()).or_insert_with(|| {
            let times: Vec<f32> = (0..p.poses.len()).map(|t| t as f32 / options.fps).collect();
            b.floats(&times, 1, None, true)
        });
    }
    let mut scene_nodes = Vec::new();
    let mut channels = Vec::new();
    let mut samplers = Vec::new();
    let glb_format = JointsFormat::default();
    for person in people {
        let frames = person.poses.len();
        let time_accessor = time_accessors[&frames];
        let rig = person.rig.with_format(glb_format);
        let format = person.rig.format();
        let prefix = if people.len() > 1 {
            format!("{}_", person.name)
        } else {
            String::new()
        };
        // Joint nodes: indices follow the rig's, offset by what is already in the document.
        let first_node = b.root.nodes.len() as u32;
        for j in 0..rig.len() {
            let children: Vec<json::Index<json::Node>> = rig
                .children(j)
                .map(|c| json::Index::new(first_node + c as u32))
                .collect();
            let q = rig.rest_rotations()[j];
            b.root.push(json::Node {
                name: Some(format!("{prefix}{}", rig.names()[j])),
                translation: Some(f32s(rig.offsets()[j])),
                rotation: Some(json::scene::UnitQuaternion(
                    [q.x, q.y, q.z, q.w].map(|v| v as f32),
                )),
                children: (!children.is_empty()).then_some(children),
                ..Default::default()
            });
        }
        let joint_node = |j: usize| json::Index::<json::Node>::new(first_node + j as u32);
        scene_nodes.push(joint_node(0));

        // Channels: every joint's rotation, the root joint's translation.
        for j in 0..rig.len() {
            let mut values = Vec::with_capacity(frames * 4);
            let mut last: Option<Quat> = None;
            for pose in person.poses {
                let mut q = format
                    .rotation_to_canonical_axes(pose.rotations[j])
                    .normalized();
                // Neighbouring keys in one hemisphere: interpolation takes the short way.
                if last.is_some_and(|l| l.w * q.w + l.x * q.x + l.y * q.y + l.z * q.z < 0.0) {
                    q = Quat {
                        w: -q.w,
                        x: -q.x,
                        y: -q.y,
                        z: -q.z,
                    };
                }
                last = Some(q);
                values.extend([q.x, q.y, q.z, q.w].map(|v| v as f32));
            }
            let output = b.floats(&values, 4, None, false);
            samplers.push(linear(time_accessor, output));
            channels.push((joint_node(j), json::animation::Property::Rotation));
        }
        let root = person.poses[0].root;
        let translations: Vec<f32> = person
            .poses
            .iter()
            .flat_map(|pose| f32s(format.point_to_canonical(pose.root_translation)))
            .collect();
        let output = b.floats(&translations, 3, None, false);
        samplers.push(linear(time_accessor, output));
        channels.push((joint_node(root), json::animation::Property::Translation));

        // The skin, with or without a body: importers make an armature of a skin's joints.
        let (rest_pos, rest_rot) = rig.rest_world();
        let ibm: Vec<f32> = (0..rig.len())
            .flat_map(|j| inverse_bind(rest_rot[j], rest_pos[j]))
            .collect();
        let ibm = b.floats(&ibm, 16, None, false);
        let skin = b.root.push(json::Skin {
            extensions: None,
            extras: Default::default(),
            inverse_bind_matrices: Some(ibm),
            joints: (0..rig.len()).map(joint_node).collect(),
            name: Some(format!("{}skin", prefix)),
            skeleton: Some(joint_node(0)),
        });
        if options.bodies {
            // A capsule per bone (joint to child, or to its end site), on the bone's joint.
            let mut positions = Vec::new();
            let mut normals = Vec::new();
            let mut joints: Vec<u16> = Vec::new();
            let mut indices = Vec::new();
            let mut bones: Vec<(usize, Vec3, Vec3)> = Vec::new();
            for j in 0..rig.len() {
                if let Some(p) = rig.parents()[j] {
                    bones.push((p, rest_pos[p], rest_pos[j]));
                }
                if let Some(e) = rig.end_sites()[j] {
                    bones.push((j, rest_pos[j], add(rest_pos[j], rest_rot[j].rotate(e))));
                }
            }
            for (joint, a, z) in bones {
                let length = norm(sub(z, a));
                if length < 1e-3 {
                    continue;
                }
                let (p, n, i) = capsule(a, z, capsule_radius(length), positions.len() as u32);
                joints.extend(std::iter::repeat_n([joint as u16, 0, 0, 0], p.len()).flatten());
                positions.extend(p);
                normals.extend(n);
                indices.extend(i);
            }
            if !positions.is_empty() {
                let flat = |v: &[Vec3]| -> Vec<f32> { v.iter().flat_map(|p| f32s(*p)).collect() };
                let target = Some(json::buffer::Target::ArrayBuffer);
                let pos = b.floats(&flat(&positions), 3, target, true);
                let nor = b.floats(&flat(&normals), 3, target, false);
                let joint_bytes: Vec<u8> = joints.iter().flat_map(|v| v.to_le_bytes()).collect();
                let jnt = b.accessor(
                    &joint_bytes,
                    positions.len(),
                    json::accessor::ComponentType::U16,
                    json::accessor::Type::Vec4,
                    target,
                    None,
                );
                let weights: Vec<f32> =
                    std::iter::repeat_n([1.0f32, 0.0, 0.0, 0.0], positions.len())
                        .flatten()
                        .collect();
                let wgt = b.floats(&weights, 4, target, false);
                let index_bytes: Vec<u8> = indices.iter().flat_map(|v| v.to_le_bytes()).collect();
                let idx = b.accessor(
                    &index_bytes,
                    indices.len(),
                    json::accessor::ComponentType::U32,
                    json::accessor::Type::Scalar,
                    Some(json::buffer::Target::ElementArrayBuffer),
                    None,
                );
                let c = person.color;
                let material = b.root.push(json::Material {
                    name: Some(format!("{}body", prefix)),
                    pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                        base_color_factor: json::material::PbrBaseColorFactor([
                            c[0], c[1], c[2], 1.0,
                        ]),
                        metallic_factor: json::material::StrengthFactor(0.0),
                        roughness_factor: json::material::StrengthFactor(0.8),
                        ..Default::default()
                    },
                    ..Default::default()
                });
                let mut attributes = BTreeMap::new();
                attributes.insert(Checked::Valid(json::mesh::Semantic::Positions), pos);
                attributes.insert(Checked::Valid(json::mesh::Semantic::Normals), nor);
                attributes.insert(Checked::Valid(json::mesh::Semantic::Joints(0)), jnt);
                attributes.insert(Checked::Valid(json::mesh::Semantic::Weights(0)), wgt);
                let mesh = b.root.push(json::Mesh {
                    extensions: None,
                    extras: Default::default(),
                    name: Some(format!("{}body", prefix)),
                    primitives: vec![json::mesh::Primitive {
                        attributes,
                        extensions: None,
                        extras: Default::default(),
                        indices: Some(idx),
                        material: Some(material),
                        mode: Checked::Valid(json::mesh::Mode::Triangles),
                        targets: None,
                    }],
                    weights: None,
                });
                let body = b.root.push(json::Node {
                    name: Some(format!("{}body", prefix)),
                    mesh: Some(mesh),
                    skin: Some(skin),
                    ..Default::default()
                });
                scene_nodes.push(body);
            }
        }
    }
    b.root.animations.push(json::Animation {
        extensions: None,
        extras: Default::default(),
        channels: channels
            .into_iter()
            .enumerate()
            .map(|(i, (node, path))| json::animation::Channel {
                sampler: json::Index::new(i as u32),
                target: json::animation::Target {
                    extensions: None,
                    extras: Default::default(),
                    node,
                    path: Checked::Valid(path),
                },
                extensions: None,
                extras: Default::default(),
            })
            .collect(),
        name: Some("troupe".into()),
        samplers,
    });
    let scene = b.root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some("troupe".into()),
        nodes: scene_nodes,
    });
    b.root.scene = Some(scene);
    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    b.root.buffers.push(json::Buffer {
        byte_length: USize64::from(b.bin.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let mut text = json::serialize::to_vec(&b.root)
        .map_err(|e| bad(format!("the document did not serialise: {e}")))?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + b.bin.len();
    let total =
        u32::try_from(total).map_err(|_| bad(format!("{total} bytes: GLB holds at most 4 GiB")))?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(b.bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b.bin);
    Ok(out)
}

/// [`write_glb`] into the file at `path`, atomically: a failure leaves no partial file.
pub fn write_glb_file(path: &Path, people: &[GltfPerson], options: &GltfOptions) -> Result<()> {
    let bytes = write_glb(people, options)?;
    crate::shared::files::write_atomically(path, &bytes)
}

// -------------------------------------------------------------------------------------------
// Reading a rig: the skeleton of a skin in a `.glb` (or `.gltf` JSON) file.

/// The largest glTF file troupe reads a rig from: 256 MiB.
pub const MAX_GLTF_BYTES: usize = 1 << 28;

/// The JSON document of a `.glb` (its first chunk) or of a `.gltf` text.
fn gltf_json<'a>(bytes: &'a [u8], label: &str) -> Result<&'a [u8]> {
    let bad = |m: String| Error::InvalidInput(format!("{label}: {m}"));
    if bytes.len() > MAX_GLTF_BYTES {
        return Err(bad(format!(
            "{} bytes; troupe reads rigs from files of at most {MAX_GLTF_BYTES}",
            bytes.len()
        )));
    }
    if !bytes.starts_with(b"glTF") {
        return Ok(bytes);
    }
    let word = |at: usize| -> Option<usize> {
        Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?) as usize)
    };
    let (version, length, chunk, kind) = (word(4), word(8), word(12), bytes.get(16..20));
    if version != Some(2) {
        return Err(bad("not a glTF 2.0 binary file".into()));
    }
    if length != Some(bytes.len()) || kind != Some(b"JSON") {
        return Err(bad(
            "the binary header's length or first chunk is not what the file holds".into(),
        ));
    }
    let chunk = chunk.expect("the header's words were read");
    bytes
        .get(20..20usize.saturating_add(chunk))
        .filter(|_| chunk <= bytes.len())
        .ok_or_else(|| bad("the JSON chunk runs past the end of the file".into()))
}

/// A node's local transform (translation, rotation) from its TRS or matrix; its scale must be 1.
fn node_transform(node: &json::Node, name: &str, label: &str) -> Result<(Vec3, Quat)> {
    let bad = |m: &str| Error::InvalidInput(format!("{label}: node {name:?}: {m}"));
    let unit_scale = |s: [f64; 3]| s.iter().all(|v| (v - 1.0).abs() < 1e-4);
    if let Some(m) = node.matrix {
        let m = m.map(f64::from);
        let col = |c: usize| [m[4 * c], m[4 * c + 1], m[4 * c + 2]];
        if m.iter().any(|v| !v.is_finite()) || !unit_scale([0, 1, 2].map(|c| norm(col(c)))) {
            return Err(bad("its matrix is not a rotation and translation"));
        }
        let rows = [0, 1, 2].map(|r| [col(0)[r], col(1)[r], col(2)[r]]);
        return Ok((col(3), Quat::from_matrix(rows)));
    }
    let t = node.translation.unwrap_or([0.0; 3]).map(f64::from);
    let r = node
        .rotation
        .map_or([0.0, 0.0, 0.0, 1.0], |q| q.0)
        .map(f64::from);
    let s = node.scale.unwrap_or([1.0; 3]).map(f64::from);
    if t.iter().chain(&r).chain(&s).any(|v| !v.is_finite()) {
        return Err(bad("a transform value is not finite"));
    }
    if !unit_scale(s) {
        return Err(bad(
            "scaled joints are not supported (apply the scale in your tool)",
        ));
    }
    let q = Quat::from_wxyz([r[3], r[0], r[1], r[2]]);
    let len = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
    if (len - 1.0).abs() > 1e-3 {
        return Err(bad("its rotation is not a unit quaternion"));
    }
    Ok((t, q.normalized()))
}

/// The rig of skin `skin` in a glTF file's bytes (`.glb`, or `.gltf` JSON): the skin's joints
/// with the hierarchy their nodes form, their nodes' transforms as the rest pose (the transforms
/// of nodes above the skeleton folded into its root), metres, Y up. Joints without a name are
/// called `joint<N>`. `label` names the file in messages.
pub fn read_gltf_rig(bytes: &[u8], skin: usize, label: &str) -> Result<Rig> {
    let bad = |m: String| Error::InvalidInput(format!("{label}: {m}"));
    let root: json::Root = serde_json::from_slice(gltf_json(bytes, label)?)
        .map_err(|e| bad(format!("not a glTF document: {e}")))?;
    let skins = root.skins.len();
    let joints: Vec<usize> = root
        .skins
        .get(skin)
        .ok_or_else(|| bad(format!("skin {skin}: the file has {skins} skins")))?
        .joints
        .iter()
        .map(|j| j.value())
        .collect();
    let n = root.nodes.len();
    if joints.is_empty() || joints.len() > crate::motion::rig::MAX_RIG_JOINTS {
        return Err(bad(format!(
            "skin {skin} has {} joints; 1 to {} are allowed",
            joints.len(),
            crate::motion::rig::MAX_RIG_JOINTS
        )));
    }
    // Each node's parent; a node with two parents, or a cycle, is no tree.
    let mut parent = vec![None; n];
    for (p, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten() {
            let c = c.value();
            if c >= n || parent[c].is_some() || c == p {
                return Err(bad(format!(
                    "node {p}: child {c} is out of range or has two parents"
                )));
            }
            parent[c] = Some(p);
        }
    }
    let depth_ok = |mut at: usize| {
        for _ in 0..=n {
            match parent[at] {
                Some(p) => at = p,
                None => return true,
            }
        }
        false
    };
    let mut seen = std::collections::HashSet::new();
    if joints.iter().any(|&j| j >= n || !seen.insert(j)) || (0..n).any(|i| !depth_ok(i)) {
        return Err(bad(
            "a joint is not a node or is listed twice, or the nodes form a cycle".into(),
        ));
    }
    let is_joint = |i: usize| joints.contains(&i);
    let joint_parent = |j: usize| {
        let mut at = parent[j];
        while let Some(p) = at {
            if is_joint(p) {
                return Some(p);
            }
            at = parent[p];
        }
        None
    };
    let roots: Vec<usize> = joints
        .iter()
        .copied()
        .filter(|&j| joint_parent(j).is_none())
        .collect();
    if roots.len() != 1 {
        return Err(bad(format!(
            "skin {skin}'s joints form {} trees; a rig is one",
            roots.len()
        )));
    }
    // The skin's order when parents come first in it, else depth first from the root.
    let position = |j: usize| joints.iter().position(|&x| x == j);
    let parents_first = joints
        .iter()
        .enumerate()
        .all(|(k, &j)| joint_parent(j).is_none_or(|p| position(p) < Some(k)));
    let mut order = Vec::with_capacity(joints.len());
    let mut stack = if parents_first {
        order.clone_from(&joints);
        Vec::new()
    } else {
        vec![roots[0]]
    };
    while let Some(j) = stack.pop() {
        order.push(j);
        let mut children: Vec<usize> = joints
            .iter()
            .copied()
            .filter(|&c| joint_parent(c) == Some(j))
            .collect();
        children.reverse();
        stack.extend(children);
    }
    let mut names: Vec<String> = Vec::with_capacity(order.len());
    let mut rig_joints = Vec::with_capacity(order.len());
    for &j in &order {
        let node = &root.nodes[j];
        let mut name = node.name.clone().unwrap_or_else(|| format!("joint{j}"));
        if names.contains(&name) {
            name = format!("{name}_{j}");
        }
        let (mut offset, mut rotation) = node_transform(node, &name, label)?;
        // Nodes between a joint and its joint parent (or above the root) are folded in.
        let stop = joint_parent(j);
        let mut at = parent[j];
        while at.is_some() && at != stop {
            let p = at.expect("checked");
            let (t, q) = node_transform(&root.nodes[p], &format!("node {p}"), label)?;
            offset = add(t, q.rotate(offset));
            rotation = q * rotation;
            at = parent[p];
        }
        rig_joints.push(crate::motion::rig::RigJoint {
            name: name.clone(),
            parent: stop.map(|p| order.iter().position(|&o| o == p).expect("parents first")),
            offset,
            rotation,
            end_site: None,
        });
        names.push(name);
    }
    Rig::new(label, rig_joints, JointsFormat::default())
}

/// [`read_gltf_rig`] of the file at `path`.
pub fn read_gltf_rig_file(path: &Path, skin: usize) -> Result<Rig> {
    let label = path.display().to_string();
    let bytes = crate::shared::files::read_bounded(path, MAX_GLTF_BYTES as u64, "glTF files")?;
    read_gltf_rig(&bytes, skin, &label)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::JointMap;

    fn poses(rig: &Rig, frames: usize) -> Vec<RigPose> {
        let rest = crate::motion::Skeleton::t2m22().rest_positions();
        let clip: Vec<Vec<Vec3>> = (0..frames).map(|_| rest.clone()).collect();
        crate::motion::retarget_clip(rig, &JointMap::builtin(), &clip, None, Default::default())
            .unwrap()
    }

    #[test]
    fn bad_people_are_refused_with_the_reason() {
        let rig = Rig::t2m22();
        let good = poses(&rig, 3);
        let mut nan = good.clone();
        nan[1].rotations[3].x = f64::NAN;
        let mut short = good.clone();
        short[2].rotations.pop();
        let mut moved = good.clone();
        moved[1].root = 4;
        fn person<'a>(rig: &'a Rig, poses: &'a [RigPose]) -> GltfPerson<'a> {
            GltfPerson {
                name: "a",
                rig,
                poses,
                color: [0.2, 0.4, 0.6],
            }
        }
        let person = |poses| person(&rig, poses);
        let slow = GltfOptions {
            fps: 0.0,
            ..Default::default()
        };
        let ok = GltfOptions::default();
        let cases: Vec<(Vec<GltfPerson>, &GltfOptions, &str)> = vec![
            (vec![], &ok, "no people"),
            (vec![person(&[])], &ok, "0 frames"),
            (vec![person(&good), person(&[])], &ok, "0 frames"),
            (vec![person(&good)], &slow, "fps"),
            (vec![person(&nan)], &ok, "finite rotations"),
            (vec![person(&short)], &ok, "finite rotations"),
            (vec![person(&moved)], &ok, "same root joint"),
            (
                vec![GltfPerson {
                    color: [2.0, 0.0, 0.0],
                    ..person(&good)
                }],
                &ok,
                "colour",
            ),
        ];
        for (people, options, reason) in cases {
            let err = write_glb(&people, options).unwrap_err().to_string();
            assert!(err.contains(reason), "{reason}: {err}");
        }
        let bytes = write_glb(&[person(&good)], &ok).unwrap();
        assert_eq!(&bytes[..4], b"glTF");
        // People of different lengths: each keeps its own keys.
        let two = write_glb(&[person(&good), person(&good[..2])], &ok).unwrap();
        assert!(two.len() > bytes.len());
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
            bytes.len()
        );
    }

    #[test]
    fn a_written_rig_reads_back_from_its_skin() {
        let rig = Rig::t2m22();
        let good = poses(&rig, 2);
        let person = GltfPerson {
            name: "a",
            rig: &rig,
            poses: &good,
            color: [0.2, 0.4, 0.6],
        };
        let bytes = write_glb(&[person], &GltfOptions::default()).unwrap();
        let back = read_gltf_rig(&bytes, 0, "a.glb").unwrap();
        assert_eq!(back.names(), rig.names());
        let ((a, _), (b, _)) = (rig.rest_world(), back.rest_world());
        for (p, q) in a.iter().zip(&b) {
            assert!(norm(sub(*p, *q)) < 1e-6, "{p:?} vs {q:?}");
        }
        // Hostile files are refused with the reason.
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (b"glTF\x01\x00\x00\x00".to_vec(), "not a glTF 2.0"),
            (bytes[..bytes.len() - 4].to_vec(), "length"),
            (b"{}".to_vec(), "not a glTF document"),
            (br#"{"asset": {"version": "2.0"}, "skins": []}"#.to_vec(), "has 0 skins"),
            (
                br#"{"asset": {"version": "2.0"}, "nodes": [{"children": [1]}, {"children": [0]}],
                    "skins": [{"joints": [0, 1]}]}"#
                    .to_vec(),
                "cycle",
            ),
            (
                br#"{"asset": {"version": "2.0"}, "nodes": [{"scale": [2, 2, 2]}],
                    "skins": [{"joints": [0]}]}"#
                    .to_vec(),
                "scaled joints",
            ),
            (
                br#"{"asset": {"version": "2.0"}, "nodes": [{}, {}], "skins": [{"joints": [0, 1]}]}"#
                    .to_vec(),
                "2 trees",
            ),
        ];
        for (file, reason) in cases {
            let err = read_gltf_rig(&file, 0, "x.glb").unwrap_err().to_string();
            assert!(err.contains(reason), "{reason}: {err}");
        }
    }

    #[test]
    fn a_capsule_is_closed_and_faces_out() {
        let (a, b, r) = ([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.1);
        let (pos, nor, idx) = capsule(a, b, r, 0);
        assert_eq!(idx.len() % 3, 0);
        // Every triangle's winding agrees with the outward normals of its corners.
        for t in idx.chunks(3) {
            let [p, q, s] = [t[0], t[1], t[2]].map(|i| pos[i as usize]);
            let n = cross(sub(q, p), sub(s, p));
            let out = add(
                add(nor[t[0] as usize], nor[t[1] as usize]),
                nor[t[2] as usize],
            );
            assert!(crate::motion::vec3::dot(n, out) > 0.0, "{t:?} faces in");
        }
        // Every vertex is r from the segment.
        for p in &pos {
            let y = p[1].clamp(0.0, 1.0);
            let d = norm(sub(*p, [0.0, y, 0.0]));
            assert!((d - r).abs() < 1e-9, "{p:?}");
        }
    }
}
