//! The data a picture shows: people, each a clip of t2m-22 joint positions in troupe's canonical
//! axes (metres, +Y up), with a name and a colour; the frame rate and a title. Everything is
//! checked on the way in, so that rendering cannot fail on the data.

use ndarray::{Array3, ArrayView2, ArrayView3};

use crate::motion::world::FPS_RANGE;
use crate::motion::{JointsFormat, Skeleton, T2M22_JOINTS};
use crate::shared::error::{Error, Result};
use crate::viewer::camera::Camera;

/// The most people a scene holds.
pub const MAX_PEOPLE: usize = 8;

/// The most frames one person may have (10 minutes at 30 fps).
pub const MAX_FRAMES: usize = 18_000;

/// The longest person name, in characters.
pub const MAX_NAME_CHARS: usize = 64;

/// The longest title, in characters.
pub const MAX_TITLE_CHARS: usize = 200;

/// The largest coordinate accepted, metres: anything farther is not a person in a room (and is
/// more likely a unit mistake).
pub const MAX_COORDINATE_M: f32 = 10_000.0;

/// Default colours, one per person in the order they are added (matplotlib's `tab10` without its
/// grey): actor blue `#1f77b4`, reactor orange `#ff7f0e`, then green, red, purple, brown, pink
/// and cyan.
pub const PALETTE: [[u8; 3]; MAX_PEOPLE] = [
    [0x1f, 0x77, 0xb4],
    [0xff, 0x7f, 0x0e],
    [0x2c, 0xa0, 0x2c],
    [0xd6, 0x27, 0x28],
    [0x94, 0x67, 0xbd],
    [0x8c, 0x56, 0x4b],
    [0xe3, 0x77, 0xc2],
    [0x17, 0xbe, 0xcf],
];

/// Height of the floor below the scene's lowest joint, metres: joints are the centres of the
/// ankles and toes, which sit about this far above the ground (the neutral body's lowest joint
/// is 0.02 m above its floor).
pub const FLOOR_BELOW_LOWEST_JOINT_M: f32 = 0.02;

/// One person of a scene: a name, a colour and joint positions `[frames][22][3]` in canonical
/// axes (metres, +Y up).
#[derive(Debug, Clone, PartialEq)]
pub struct Person {
    name: String,
    colour: [u8; 3],
    positions: Array3<f32>,
}

impl Person {
    /// The name shown in the legend.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The colour as `[r, g, b]`.
    pub fn colour(&self) -> [u8; 3] {
        self.colour
    }

    /// The colour as CSS hex, `#rrggbb`.
    pub fn colour_hex(&self) -> String {
        let [r, g, b] = self.colour;
        format!("#{r:02x}{g:02x}{b:02x}")
    }

    /// Replaces the colour (defaults come from [`PALETTE`]).
    pub fn set_colour(&mut self, rgb: [u8; 3]) -> &mut Person {
        self.colour = rgb;
        self
    }

    /// Joint positions `[frames][22][3]`, canonical axes, metres.
    pub fn positions(&self) -> ArrayView3<'_, f32> {
        self.positions.view()
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.positions.shape()[0]
    }

    /// The pose shown at scene frame `t`, `[22][3]`: frame `t`, or the last frame for a person
    /// whose clip is shorter than the scene (they hold their last pose).
    pub fn pose(&self, t: usize) -> ArrayView2<'_, f32> {
        let last = self.frames() - 1;
        self.positions.index_axis(ndarray::Axis(0), t.min(last))
    }
}

/// People moving on the t2m-22 skeleton: what [`Scene::to_html`] and [`Scene::write_gif`]
/// show. Scene frame `t` is at `t / fps` seconds; the scene lasts as long as its longest person.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    title: String,
    fps: f32,
    people: Vec<Person>,
}

impl Scene {
    /// An empty scene at `fps` frames per second (in [1, 1000]) with a `title` of at most
    /// [`MAX_TITLE_CHARS`] characters (it may be empty).
    pub fn new(fps: f32, title: impl Into<String>) -> Result<Scene> {
        if !FPS_RANGE.contains(&fps) {
            return Err(Error::InvalidInput(format!(
                "viewer: a scene at {fps} fps: the frame rate must be in [{}, {}]",
                FPS_RANGE.start(),
                FPS_RANGE.end()
            )));
        }
        let title = title.into();
        let chars = title.chars().count();
        if chars > MAX_TITLE_CHARS {
            return Err(Error::InvalidInput(format!(
                "viewer: the title has {chars} characters, at most {MAX_TITLE_CHARS} are allowed"
            )));
        }
        Ok(Scene {
            title,
            fps,
            people: Vec::new(),
        })
    }

    /// A scene of people whose positions are measured as `format` says (units, up axis,
    /// handedness; its frame rate becomes the scene's), each `[frames][22][3]`, converted to
    /// canonical axes. Fails as [`Scene::new`] and [`Scene::add_person`] do.
    pub fn from_world(
        title: impl Into<String>,
        format: &JointsFormat,
        people: &[(&str, ArrayView3<'_, f32>)],
    ) -> Result<Scene> {
        format.validate()?;
        let mut scene = Scene::new(format.fps, title)?;
        for (name, positions) in people {
            scene.add_person_from_world(*name, *positions, format)?;
        }
        Ok(scene)
    }

    /// Adds a person: `positions` are `[frames][22][3]` t2m-22 joints in canonical axes (metres,
    /// +Y up), 1 to [`MAX_FRAMES`] frames, finite and within [`MAX_COORDINATE_M`] of the origin.
    /// `name` is 1 to [`MAX_NAME_CHARS`] characters. The colour is the next of [`PALETTE`];
    /// change it on the person returned. At most [`MAX_PEOPLE`] people.
    pub fn add_person(
        &mut self,
        name: impl Into<String>,
        positions: ArrayView3<'_, f32>,
    ) -> Result<&mut Person> {
        let name = name.into();
        self.check_person(&name, positions)?;
        let colour = PALETTE[self.people.len()];
        self.people.push(Person {
            name,
            colour,
            positions: positions.to_owned(),
        });
        Ok(self.people.last_mut().expect("just pushed"))
    }

    /// Adds a person whose positions `[frames][22][3]` are measured as `format` says (units, up
    /// axis, handedness; its frame rate is not used), converting them to canonical axes.
    pub fn add_person_from_world(
        &mut self,
        name: impl Into<String>,
        positions: ArrayView3<'_, f32>,
        format: &JointsFormat,
    ) -> Result<&mut Person> {
        let name = name.into();
        // Check the caller's values first, so that messages name what the caller passed.
        self.check_person(&name, positions)?;
        let canonical = positions.map_axis(ndarray::Axis(2), |p| {
            format
                .to_canonical_axes([p[0], p[1], p[2]])
                .map(|v| v as f32)
        });
        let (t, j) = canonical.dim();
        let flat: Vec<f32> = canonical.iter().flatten().copied().collect();
        let canonical = Array3::from_shape_vec((t, j, 3), flat).expect("shape kept");
        self.add_person(name, canonical.view())
    }

    fn check_person(&self, name: &str, positions: ArrayView3<'_, f32>) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidInput(format!("viewer: {m}")));
        if self.people.len() >= MAX_PEOPLE {
            return bad(format!(
                "a scene holds at most {MAX_PEOPLE} people; {name:?} would be one more"
            ));
        }
        let chars = name.chars().count();
        if chars == 0 || chars > MAX_NAME_CHARS {
            return bad(format!(
                "person {}: the name has {chars} characters, 1 to {MAX_NAME_CHARS} are allowed",
                self.people.len()
            ));
        }
        let (frames, joints, dims) = positions.dim();
        if joints != T2M22_JOINTS || dims != 3 {
            return bad(format!(
                "{name}: positions of shape [{frames}, {joints}, {dims}]; the viewer needs \
                 [frames, {T2M22_JOINTS}, 3] (t2m-22 joints)"
            ));
        }
        if frames == 0 || frames > MAX_FRAMES {
            return bad(format!(
                "{name}: {frames} frames; 1 to {MAX_FRAMES} are allowed"
            ));
        }
        for ((t, j, d), v) in positions.indexed_iter() {
            if !v.is_finite() || v.abs() > MAX_COORDINATE_M {
                let joint = Skeleton::t2m22().names()[j].clone();
                let what = if v.is_finite() {
                    format!("{v}, farther than {MAX_COORDINATE_M} m")
                } else {
                    format!("{v}")
                };
                return bad(format!(
                    "{name}: frame {t}, joint {j} ({joint}), coordinate {d} is {what}"
                ));
            }
        }
        Ok(())
    }

    /// The title.
    pub fn title(&self) -> &str {
        &self.title
    }

    /// Frames per second.
    pub fn fps(&self) -> f32 {
        self.fps
    }

    /// The people, in the order they were added.
    pub fn people(&self) -> &[Person] {
        &self.people
    }

    /// Person `index`, to change its colour.
    pub fn person_mut(&mut self, index: usize) -> Option<&mut Person> {
        self.people.get_mut(index)
    }

    /// Frames of the scene: those of its longest person (0 without people).
    pub fn frames(&self) -> usize {
        self.people.iter().map(Person::frames).max().unwrap_or(0)
    }

    /// The corners `(min, max)` of the box holding every joint of every person in every frame,
    /// or `None` without people.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for person in &self.people {
            for p in person.positions.rows() {
                for d in 0..3 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
            }
        }
        (!self.people.is_empty()).then_some((lo, hi))
    }

    /// Height of the floor both pictures draw: [`FLOOR_BELOW_LOWEST_JOINT_M`] below the lowest
    /// joint of the scene (0 without people).
    pub fn floor(&self) -> f32 {
        self.bounds()
            .map_or(0.0, |(lo, _)| lo[1] - FLOOR_BELOW_LOWEST_JOINT_M)
    }

    /// The camera both pictures start from: [`Camera::framing`] of [`Scene::bounds`] (a camera
    /// looking at the origin from the front without people).
    pub fn camera(&self) -> Camera {
        match self.bounds() {
            Some((lo, hi)) => Camera::framing(lo, hi),
            None => Camera::framing([-0.5, 0.0, -0.5], [0.5, 1.7, 0.5]),
        }
    }

    /// Fails unless the scene has someone to show.
    pub(crate) fn check_not_empty(&self) -> Result<()> {
        if self.people.is_empty() {
            return Err(Error::InvalidInput(
                "viewer: the scene has no people; add at least one".into(),
            ));
        }
        Ok(())
    }
}
