//! The animated GIF: the scene from a fixed camera (by default [`Scene::camera`], the HTML
//! player's starting view), on the player's background with its floor grid, each person in
//! their colour: bones as anti-aliased lines, joints as dots, the head as a disk. No text.
//!
//! Every `k`-th frame is drawn ([`GifOptions::stride`]) so that the GIF runs at most
//! [`GifOptions::max_fps`]; frame delays are rounded to the GIF's 10 ms ticks without drift.
//! After the first, each frame stores only the box of pixels that changed, and a frame that
//! changes nothing lengthens the one before it, so a GIF can have fewer frames than drawn.

use std::path::Path;

use crate::motion::{Skeleton, T2M22_JOINTS};
use crate::shared::error::{Error, Result};
use crate::shared::files::write_atomically;
use crate::shared::progress;
use crate::viewer::camera::Camera;
use crate::viewer::html::grid;
use crate::viewer::raster::{palette, Area, Ink, Raster, GRID};
use crate::viewer::scene::Scene;

/// Width of bones in a 360-pixel-high GIF (scaled with the shorter side), pixels.
const BONE_PX: f32 = 3.0;
/// Radius of joints in a 360-pixel-high GIF, pixels.
const JOINT_PX: f32 = 3.0;
/// Radius of the head, metres.
const HEAD_M: f32 = 0.1;

/// How [`Scene::write_gif`] draws.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GifOptions {
    /// Width in pixels, 32 to 1920 (default 480).
    pub width: u16,
    /// Height in pixels, 32 to 1920 (default 360).
    pub height: u16,
    /// The most frames per second drawn, 1 to 50 (default 15): every
    /// [`GifOptions::stride`]-th scene frame.
    pub max_fps: f32,
    /// The camera, or `None` (default) for [`Scene::camera`].
    pub camera: Option<Camera>,
    /// Loop forever (default) or play once.
    pub repeat: bool,
}

impl Default for GifOptions {
    fn default() -> Self {
        GifOptions {
            width: 480,
            height: 360,
            max_fps: 15.0,
            camera: None,
            repeat: true,
        }
    }
}

impl GifOptions {
    /// Every how many scene frames one is drawn for a scene at `fps`: the smallest `k` with
    /// `fps / k <= max_fps`.
    pub fn stride(&self, fps: f32) -> usize {
        ((fps / self.max_fps) - 1e-4).ceil().max(1.0) as usize
    }

    fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidOption(format!("viewer: GIF {m}")));
        for (what, v) in [("width", self.width), ("height", self.height)] {
            if !(32..=1920).contains(&v) {
                return bad(format!("{what} {v}: 32 to 1920 pixels are allowed"));
            }
        }
        if !(1.0..=50.0).contains(&self.max_fps) {
            return bad(format!(
                "max_fps {}: 1 to 50 frames per second are allowed",
                self.max_fps
            ));
        }
        if let Some(c) = self.camera {
            let finite = c.target.iter().all(|v| v.is_finite())
                && [c.yaw_deg, c.pitch_deg, c.distance, c.fov_deg]
                    .iter()
                    .all(|v| v.is_finite());
            if !finite
                || c.distance <= 0.0
                || !(1.0..=170.0).contains(&c.fov_deg)
                || c.pitch_deg.abs() >= 90.0
            {
                return bad(format!(
                    "camera {c:?}: needs finite values, a positive distance, a field of view \
                     in [1, 170] degrees and a pitch within (-90, 90)"
                ));
            }
        }
        Ok(())
    }
}

/// Draws scene frames on a fixed camera.
struct Painter<'a> {
    scene: &'a Scene,
    camera: Camera,
    parents: Vec<Option<usize>>,
    head: usize,
    base: Raster,
    scale: f32,
}

impl<'a> Painter<'a> {
    fn new(scene: &'a Scene, options: &GifOptions) -> Painter<'a> {
        let camera = options.camera.unwrap_or_else(|| scene.camera());
        let (w, h) = (usize::from(options.width), usize::from(options.height));
        let (wf, hf) = (w as f32, h as f32);
        let mut base = Raster::new(w, h);
        let [x0, x1, z0, z1, step] = grid(scene);
        let floor = scene.floor();
        let lines = |from: f32, to: f32| {
            let n = ((to - from) / step).round() as usize;
            (0..=n).map(move |i| from + i as f32 * step)
        };
        for x in lines(x0, x1) {
            if let Some((a, b)) = camera.project_segment([x, floor, z0], [x, floor, z1], wf, hf) {
                base.segment(a, b, 1.0, Ink::Solid(GRID));
            }
        }
        for z in lines(z0, z1) {
            if let Some((a, b)) = camera.project_segment([x0, floor, z], [x1, floor, z], wf, hf) {
                base.segment(a, b, 1.0, Ink::Solid(GRID));
            }
        }
        let skeleton = Skeleton::t2m22();
        Painter {
            scene,
            camera,
            parents: skeleton.parents().to_vec(),
            head: skeleton.index_of("head").expect("t2m-22 has a head"),
            base,
            scale: wf.min(hf) / 360.0,
        }
    }

    fn draw(&self, t: usize) -> Raster {
        let mut r = self.base.clone();
        let (w, h) = (r.width as f32, r.height as f32);
        let focal = self.camera.focal_px(w, h);
        let mut posed: Vec<(usize, [[f32; 3]; T2M22_JOINTS], f32)> = self
            .scene
            .people()
            .iter()
            .enumerate()
            .map(|(p, person)| {
                let pose = person.pose(t);
                let joints: [[f32; 3]; T2M22_JOINTS] =
                    std::array::from_fn(|j| [pose[[j, 0]], pose[[j, 1]], pose[[j, 2]]]);
                let depth = joints.iter().map(|&q| self.camera.to_camera(q)[2]).sum();
                (p, joints, depth)
            })
            .collect();
        // Farthest first, so that nearer people are drawn over them.
        posed.sort_by(|a, b| b.2.total_cmp(&a.2));
        for (p, joints, _) in posed {
            let ink = Ink::Person(p as u8);
            for (j, parent) in self.parents.iter().enumerate() {
                let Some(parent) = *parent else { continue };
                if let Some((a, b)) = self.camera.project_segment(joints[parent], joints[j], w, h) {
                    r.segment(a, b, BONE_PX * self.scale, ink);
                }
            }
            for (j, &q) in joints.iter().enumerate() {
                let c = self.camera.to_camera(q);
                let Some(at) = self.camera.project_camera(c, w, h) else {
                    continue;
                };
                let radius = if j == self.head {
                    (HEAD_M * focal / c[2]).max((JOINT_PX + 1.0) * self.scale)
                } else {
                    JOINT_PX * self.scale
                };
                r.disk(at, radius, ink);
            }
        }
        r
    }
}

/// One GIF frame: the box of pixels that changed, drawn over the frame before.
struct Patch {
    area: Area,
    pixels: Vec<u8>,
    delay_cs: i64,
}

impl Patch {
    fn write(self, encoder: &mut gif::Encoder<&mut Vec<u8>>) -> Result<()> {
        let (x, y, w, h) = self.area;
        let frame = gif::Frame {
            delay: self.delay_cs.clamp(2, i64::from(u16::MAX)) as u16,
            dispose: gif::DisposalMethod::Keep,
            left: x as u16,
            top: y as u16,
            width: w as u16,
            height: h as u16,
            buffer: self.pixels.into(),
            ..gif::Frame::default()
        };
        encoder.write_frame(&frame).map_err(gif_error)
    }
}

fn gif_error(e: gif::EncodingError) -> Error {
    Error::InvalidInput(format!("viewer: encoding the GIF failed: {e}"))
}

impl Scene {
    /// The scene as an animated GIF (see the [module documentation](self)). Fails for a scene
    /// without people and for options out of range.
    pub fn to_gif(&self, options: &GifOptions) -> Result<Vec<u8>> {
        self.check_not_empty()?;
        options.validate()?;
        let painter = Painter::new(self, options);
        let colours: Vec<[u8; 3]> = self.people().iter().map(|p| p.colour()).collect();
        let mut bytes = Vec::new();
        let mut encoder = gif::Encoder::new(
            &mut bytes,
            options.width,
            options.height,
            &palette(&colours),
        )
        .map_err(gif_error)?;
        if options.repeat {
            encoder
                .set_repeat(gif::Repeat::Infinite)
                .map_err(gif_error)?;
        }
        let stride = options.stride(self.fps());
        let centiseconds = |t: usize| (100.0 * t as f64 / f64::from(self.fps())).round() as i64;
        // The frame waiting for its delay to be known.
        let mut pending: Option<Patch> = None;
        let mut previous: Option<Raster> = None;
        for t in (0..self.frames()).step_by(stride) {
            progress::report("the GIF", t as u64 + 1, self.frames() as u64)?;
            let raster = painter.draw(t);
            let delay_cs = centiseconds(t + stride) - centiseconds(t);
            let changed = match &previous {
                None => Some((0, 0, raster.width, raster.height)),
                Some(before) => raster.changed_box(before),
            };
            match changed {
                // Nothing moved: the frame before lasts longer.
                None => {
                    if let Some(p) = pending.as_mut() {
                        p.delay_cs += delay_cs;
                    }
                }
                Some(area) => {
                    let next = Patch {
                        area,
                        pixels: raster.crop(area),
                        delay_cs,
                    };
                    if let Some(done) = pending.replace(next) {
                        done.write(&mut encoder)?;
                    }
                }
            }
            previous = Some(raster);
        }
        if let Some(done) = pending.take() {
            done.write(&mut encoder)?;
        }
        encoder
            .into_inner()
            .map_err(|e| gif_error(gif::EncodingError::Io(e)))?;
        Ok(bytes)
    }

    /// Writes [`Scene::to_gif`] to `path`: through a temporary file beside it, renamed into
    /// place, so that nothing is written on error.
    pub fn write_gif(&self, path: impl AsRef<Path>, options: &GifOptions) -> Result<()> {
        let bytes = self.to_gif(options)?;
        write_atomically(path.as_ref(), &bytes)
    }
}
