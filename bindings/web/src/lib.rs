//! troupe in the browser: [`wasm_bindgen`] bindings over the library's [`Model`] and [`Session`],
//! built for `wasm32-unknown-unknown` with SIMD (`scripts/web.sh`, `docs/WEB.md`).
//!
//! The JavaScript side sees three classes:
//!
//! - [`WebModel`]: a bundle loaded from the bytes of its tar archive (the page fetches it); what
//!   it is (family, frame rate, named conditions) and sessions on it;
//! - [`WebSession`]: one stream, `step` on feature frames or `stepJoints` on joint positions
//!   (ARMFlow), with the clean-ups of the streaming demo as options;
//! - [`WebClip`]: a BVH file read by troupe's reader as t2m-22 joint positions.
//!
//! Everything runs on the calling thread: with no threads available on `wasm32-unknown-unknown`,
//! troupe's loads and matrix products stay on it. Errors come back as JavaScript `Error`s
//! carrying troupe's message; a panic (none is expected) aborts the module, which JavaScript sees
//! as a `RuntimeError`, since wasm32 cannot unwind.

use ndarray::ArrayView3;
use troupe::motion::bvh::parse_bvh;
use troupe::motion::{JointMap, JointsFormat, Skeleton, Units, UpAxis, T2M22_JOINTS};
use troupe::{
    FootLockOptions, Model, PenetrationGuard, Reactor, ReactorOptions, Recentring, RootSmoothing,
    Session, TokenNoise,
};
use wasm_bindgen::prelude::*;

/// Joints of troupe's skeleton (t2m-22) in every joint array this module takes or gives.
pub const JOINTS: usize = T2M22_JOINTS;

#[wasm_bindgen]
extern "C" {
    #[wasm_bindgen(js_namespace = console)]
    fn error(message: &str);
}

/// Runs when the module is instantiated: a panic (none is expected) prints its message and place
/// on the console before the module aborts, instead of a bare `unreachable`.
#[wasm_bindgen(start)]
pub fn start() {
    std::panic::set_hook(Box::new(|info| {
        error(&format!("troupe-web panicked: {info}"))
    }));
}

/// The error JavaScript receives: troupe's message.
fn js_error(e: troupe::Error) -> JsError {
    JsError::new(&e.to_string())
}

fn invalid(message: &str) -> JsError {
    JsError::new(message)
}

/// A JavaScript number as a whole number in `0..=max`: refused, not wrapped, when it is not one
/// (wasm-bindgen's own `u32` parameters take 2^32 + 1 as 1, and 1.5 as 1).
fn whole(what: &str, value: f64, max: u64) -> Result<u64, JsError> {
    // Past 2^53 a number is no longer every whole number it seems to be.
    let max = max.min(1 << 53);
    if value.is_finite() && value.fract() == 0.0 && value >= 0.0 && value <= max as f64 {
        Ok(value as u64)
    } else {
        Err(invalid(&format!(
            "{what}: {value} is not a whole number from 0 to {max}"
        )))
    }
}

/// A seed given as a BigInt (0n to 2n ** 64n - 1n) or a whole Number (up to 2^53), refused when
/// out of range instead of wrapped as a plain `u64` parameter would be.
fn seed_of(seed: JsValue) -> Result<u64, JsError> {
    if seed.is_bigint() {
        u64::try_from(seed).map_err(|_| invalid("seed: a BigInt from 0n to 2n ** 64n - 1n"))
    } else if let Some(n) = seed.as_f64() {
        whole("seed", n, u64::MAX)
    } else {
        Err(invalid("seed: a BigInt or a whole number"))
    }
}

/// A loaded bundle.
#[wasm_bindgen]
pub struct WebModel {
    model: Model,
}

#[wasm_bindgen]
impl WebModel {
    /// Loads a bundle from the bytes of its uncompressed tar archive (copied; the caller's
    /// buffer may be dropped). `label` names it in error messages.
    #[wasm_bindgen(constructor)]
    pub fn new(archive: &[u8], label: &str) -> Result<WebModel, JsError> {
        let model = Model::from_archive_bytes(archive, label).map_err(js_error)?;
        Ok(WebModel { model })
    }

    /// The bundle's name (its manifest's).
    #[wasm_bindgen(getter)]
    pub fn name(&self) -> String {
        self.model.manifest().name.clone()
    }

    /// The model family: `armflow`, `umf`, `magnet` or `arflow`.
    #[wasm_bindgen(getter)]
    pub fn family(&self) -> String {
        self.model.family().to_string()
    }

    /// Motion frames per second.
    #[wasm_bindgen(getter)]
    pub fn fps(&self) -> u32 {
        self.model.fps()
    }

    /// Floats per feature frame, in and out.
    #[wasm_bindgen(getter, js_name = frameDim)]
    pub fn frame_dim(&self) -> usize {
        self.model.frame_dim()
    }

    /// Floats per latent token (the size of each noise vector).
    #[wasm_bindgen(getter, js_name = latentDim)]
    pub fn latent_dim(&self) -> usize {
        self.model.latent_dim()
    }

    /// Floats per conditioning vector.
    #[wasm_bindgen(getter, js_name = conditionDim)]
    pub fn condition_dim(&self) -> usize {
        self.model.condition_dim()
    }

    /// Motion frames per generated token.
    #[wasm_bindgen(getter, js_name = framesPerToken)]
    pub fn frames_per_token(&self) -> usize {
        self.model.frames_per_token()
    }

    /// Frames between an actor frame going in and the reactor frame of the same instant coming
    /// out, when streaming joint positions.
    #[wasm_bindgen(getter, js_name = jointsLatencyFrames)]
    pub fn joints_latency_frames(&self) -> usize {
        self.model.joints_latency_frames()
    }

    /// The names of the bundle's named conditions (the demo's partner rules), in manifest
    /// order.
    #[wasm_bindgen(js_name = conditionNames)]
    pub fn condition_names(&self) -> Vec<String> {
        self.model
            .condition_labels()
            .iter()
            .map(|l| l.name.clone())
            .collect()
    }

    /// One line on what the named condition `name` makes the model do (empty when the bundle
    /// says nothing).
    #[wasm_bindgen(js_name = conditionAbout)]
    pub fn condition_about(&self, name: &str) -> Result<String, JsError> {
        self.model
            .condition_labels()
            .iter()
            .find(|l| l.name == name)
            .map(|l| l.about.clone())
            .ok_or_else(|| invalid(&format!("the bundle has no condition named `{name}`")))
    }

    /// Whether sessions may be conditioned on a text prompt.
    #[wasm_bindgen(js_name = takesPrompts)]
    pub fn takes_prompts(&self) -> bool {
        self.model.takes_prompts()
    }

    /// A new stream with `seed`, conditioned on the named condition `condition` (`undefined`:
    /// the bundle's null condition), keeping `capacity` tokens of context (`undefined`: the
    /// bundle's). ARMFlow streams start with no clean-up; the setters turn them on.
    pub fn session(
        &self,
        seed: JsValue,
        condition: Option<String>,
        capacity: Option<f64>,
    ) -> Result<WebSession, JsError> {
        let seed = seed_of(seed)?;
        let capacity = capacity
            .map(|c| whole("capacity", c, u32::MAX.into()).map(|c| c as usize))
            .transpose()?;
        let session = if self.model.family() == "armflow" {
            let condition = condition
                .map(|name| self.model.condition_for(&name))
                .transpose()
                .map_err(js_error)?;
            let options = ReactorOptions {
                seed,
                condition,
                context_capacity: capacity,
                ..ReactorOptions::default()
            };
            self.model.session(options)
        } else if condition.is_some() {
            return Err(invalid(
                "named conditions are for ARMFlow bundles; this bundle's family has none",
            ));
        } else {
            let mut options = self.model.session_defaults().map_err(js_error)?;
            options.seed = seed;
            options.context_capacity = capacity.or(options.context_capacity);
            self.model.session(options)
        }
        .map_err(js_error)?;
        Ok(WebSession { session })
    }
}

/// One stream of a model.
#[wasm_bindgen]
pub struct WebSession {
    session: Session,
}

impl WebSession {
    fn reactor(&mut self) -> Result<&mut Reactor, JsError> {
        self.session.family_mut::<Reactor>().map_err(js_error)
    }
}

#[wasm_bindgen]
impl WebSession {
    /// Feeds actor feature frames (`n × frameDim` floats, row-major) and returns the reactor
    /// frames ready (`m × frameDim`, possibly none). On error (troupe checks the length) nothing
    /// changes.
    pub fn step(&mut self, frames: &[f32]) -> Result<Vec<f32>, JsError> {
        let out = self.session.step_flat(frames).map_err(js_error)?;
        Ok(out.frames.into_iter().collect())
    }

    /// Feeds actor joint positions (`n × 22 × 3` floats, in the joints format set, by default
    /// metres, +Y up, at the model's frame rate) and returns the reactor's (`m × 22 × 3`, same
    /// format). Every streaming family (ARMFlow, ARFlow online, MAGNet). On error nothing
    /// changes.
    #[wasm_bindgen(js_name = stepJoints)]
    pub fn step_joints(&mut self, joints: &[f32]) -> Result<Vec<f32>, JsError> {
        let per_frame = JOINTS * 3;
        if !joints.len().is_multiple_of(per_frame) {
            return Err(invalid(&format!(
                "{} floats are not whole frames of 22 joints × 3",
                joints.len()
            )));
        }
        let view = ArrayView3::from_shape((joints.len() / per_frame, JOINTS, 3), joints)
            .map_err(|e| invalid(&e.to_string()))?;
        let poses = self.session.step_joints(view).map_err(js_error)?;
        Ok(poses
            .iter()
            .flat_map(|p| p.positions.iter().flatten().copied())
            .collect())
    }

    /// The joints format of [`WebSession::step_joints`]: `units` one of `m`, `cm`, `mm`, `in`;
    /// `up` `y` or `z`; `fps` the caller's frame rate (troupe resamples to the model's).
    /// Forgets the joint frames and placement streamed so far.
    #[wasm_bindgen(js_name = setJointsFormat)]
    pub fn set_joints_format(&mut self, units: &str, up: &str, fps: f32) -> Result<(), JsError> {
        let units = match units {
            "m" => Units::Meters,
            "cm" => Units::Centimeters,
            "mm" => Units::Millimeters,
            "in" => Units::Inches,
            other => {
                return Err(invalid(&format!(
                    "unknown units `{other}`: m, cm, mm or in"
                )))
            }
        };
        let up = match up {
            "y" => UpAxis::Y,
            "z" => UpAxis::Z,
            other => return Err(invalid(&format!("unknown up axis `{other}`: y or z"))),
        };
        let format = JointsFormat {
            units,
            up,
            fps,
            ..JointsFormat::default()
        };
        self.session.set_joints_format(format).map_err(js_error)
    }

    /// Starts the stream again from nothing (options and condition kept).
    pub fn reset(&mut self) {
        self.session.reset();
    }

    /// Conditions the stream on the named condition `name` from the next token on (ARMFlow).
    #[wasm_bindgen(js_name = setCondition)]
    pub fn set_condition(&mut self, model: &WebModel, name: &str) -> Result<(), JsError> {
        let vector = model.model.condition_for(name).map_err(js_error)?;
        self.session.set_condition(Some(&vector)).map_err(js_error)
    }

    /// Conditions the stream on a conditioning vector of the model's condition size
    /// (`undefined`: the bundle's null condition) from the next token on (ARMFlow).
    #[wasm_bindgen(js_name = setConditionVector)]
    pub fn set_condition_vector(&mut self, vector: Option<Vec<f32>>) -> Result<(), JsError> {
        self.session
            .set_condition(vector.as_deref())
            .map_err(js_error)
    }

    /// Classifier-free guidance scale (streams that take one: ARMFlow, guided above 1).
    #[wasm_bindgen(js_name = setCfgScale)]
    pub fn set_cfg_scale(&mut self, scale: f32) -> Result<(), JsError> {
        self.session.set_cfg_scale(scale).map_err(js_error)
    }

    /// Queues the noise of the next token (ARMFlow): `actor`, the standard normals of the
    /// actor's posterior sample, and `reactor`, the reactor's starting noise, `latentDim`
    /// floats each; queued tokens use them instead of the seeded generator's, to reproduce a
    /// run exactly.
    #[wasm_bindgen(js_name = armflowQueueNoise)]
    pub fn armflow_queue_noise(
        &mut self,
        actor: Vec<f32>,
        reactor: Vec<f32>,
    ) -> Result<(), JsError> {
        self.reactor()?
            .queue_noise(TokenNoise { actor, reactor })
            .map_err(js_error)
    }

    /// Conditions the stream on a text prompt from the next token on (ARMFlow bundles that take
    /// prompts).
    #[wasm_bindgen(js_name = setPrompt)]
    pub fn set_prompt(&mut self, prompt: &str) -> Result<(), JsError> {
        self.session.set_prompt(prompt).map_err(js_error)
    }

    /// MeanFlow steps per token (ARMFlow; at least 1).
    #[wasm_bindgen(js_name = setSteps)]
    pub fn set_steps(&mut self, steps: f64) -> Result<(), JsError> {
        let steps = whole("steps", steps, u32::MAX.into())? as u32;
        self.session.set_steps(steps).map_err(js_error)
    }

    /// The penetration guard: the reactor pushed out of the actor's body by at least `d_safe`
    /// metres, at most `max_speed` m/s; `enabled = false` turns it off (every streaming family).
    #[wasm_bindgen(js_name = setPenetrationGuard)]
    pub fn set_penetration_guard(
        &mut self,
        enabled: bool,
        d_safe: f64,
        max_speed: f64,
    ) -> Result<(), JsError> {
        let guard = enabled.then_some(PenetrationGuard { d_safe, max_speed });
        self.session.set_penetration_guard(guard).map_err(js_error)
    }

    /// Root smoothing with time constant `tau` seconds; `enabled = false` turns it off (every
    /// streaming family).
    #[wasm_bindgen(js_name = setRootSmoothing)]
    pub fn set_root_smoothing(&mut self, enabled: bool, tau: f64) -> Result<(), JsError> {
        let smoothing = enabled.then_some(RootSmoothing { time_constant: tau });
        self.session.set_root_smoothing(smoothing).map_err(js_error)
    }

    /// Recentring: before each token, when the actor is more than `distance` metres from the
    /// networks' centre, the centre moves to it and their state is rebuilt from the last 8
    /// tokens; `enabled = false` turns it off (ARMFlow).
    #[wasm_bindgen(js_name = armflowSetRecentring)]
    pub fn armflow_set_recentring(&mut self, enabled: bool, distance: f64) -> Result<(), JsError> {
        let recentring = enabled.then_some(Recentring { distance });
        self.reactor()?.set_recentring(recentring).map_err(js_error)
    }

    /// The foot lock with troupe's defaults; `enabled = false` turns it off (streams whose
    /// frames carry contact labels: ARMFlow, ARFlow).
    #[wasm_bindgen(js_name = setFootLock)]
    pub fn set_foot_lock(&mut self, enabled: bool) -> Result<(), JsError> {
        let lock = enabled.then(FootLockOptions::default);
        self.session.set_foot_lock(lock).map_err(js_error)
    }

    /// Tokens generated since the stream began.
    #[wasm_bindgen(getter, js_name = tokensGenerated)]
    pub fn tokens_generated(&self) -> f64 {
        self.session.tokens_generated() as f64
    }

    /// Frames emitted since the stream began.
    #[wasm_bindgen(getter, js_name = framesEmitted)]
    pub fn frames_emitted(&self) -> f64 {
        self.session.frames_emitted() as f64
    }
}

/// A BVH file's motion as troupe's t2m-22 joints: metres, +Y up, at the file's frame rate.
#[wasm_bindgen]
pub struct WebClip {
    positions: Vec<f32>,
    frames: usize,
    fps: f32,
    inferred: Vec<String>,
}

#[wasm_bindgen]
impl WebClip {
    /// Reads a BVH file's bytes with troupe's reader and built-in joint map (Mixamo, LAFAN1,
    /// CMU, Rigify... names); joints the rig lacks are inferred, and `inferred` says which.
    /// `label` names the file in error messages.
    #[wasm_bindgen(js_name = fromBvh)]
    pub fn from_bvh(bytes: &[u8], label: &str) -> Result<WebClip, JsError> {
        if troupe::motion::fbx::is_fbx(bytes) {
            return Err(JsError::new(&format!(
                "{label} is an FBX file: this page reads BVH (troupe's library reads FBX too; \
                 Blender can export BVH)"
            )));
        }
        let bvh = parse_bvh(bytes, label).map_err(js_error)?;
        let joints = bvh
            .to_t2m22(&JointMap::builtin(), None, label)
            .map_err(js_error)?;
        let metres = joints.format.units.meters() as f32;
        let frames = joints.positions.shape()[0];
        Ok(WebClip {
            positions: joints.positions.iter().map(|v| v * metres).collect(),
            frames,
            fps: joints.format.fps,
            inferred: joints.inferred,
        })
    }

    /// `frames × 22 × 3` floats.
    #[wasm_bindgen(getter)]
    pub fn positions(&self) -> Vec<f32> {
        self.positions.clone()
    }

    /// Frames in the clip.
    #[wasm_bindgen(getter)]
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The file's frame rate.
    #[wasm_bindgen(getter)]
    pub fn fps(&self) -> f32 {
        self.fps
    }

    /// The joints the rig lacked and how they were placed, one line each.
    #[wasm_bindgen(getter)]
    pub fn inferred(&self) -> Vec<String> {
        self.inferred.clone()
    }
}

/// The names of the 22 joints, in the order of every joint array.
#[wasm_bindgen(js_name = jointNames)]
pub fn joint_names() -> Vec<String> {
    Skeleton::t2m22().names().to_vec()
}

/// Each joint's parent index (-1 for the root), in the order of every joint array.
#[wasm_bindgen(js_name = jointParents)]
pub fn joint_parents() -> Vec<i32> {
    Skeleton::t2m22()
        .parents()
        .iter()
        .map(|p| p.map_or(-1, |p| p as i32))
        .collect()
}
