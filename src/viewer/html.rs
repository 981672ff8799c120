//! The HTML player: one self-contained file (`player.html` beside this file, with the scene's
//! data substituted), no network, no external script, style or font.
//!
//! What the page does: it animates every person as a 3-D skeleton (bones between each joint and
//! its parent, joints as dots, the head as a disk, one colour per person) over a floor grid, on a
//! canvas filling the window, seen through the scene's [`Camera`](crate::viewer::Camera) with
//! the same projection as [`Camera::project`](crate::viewer::Camera::project). Drag to orbit,
//! wheel to zoom, double-click to reset the view; a bar at the bottom has play/pause, a frame
//! slider, the frame counter and a speed selector; space plays and pauses, the arrow keys step.
//!
//! Query parameters set its initial state, so that a test (or a link) shows one frame
//! deterministically: `frame` (0-based, clamped), `paused` (`1` to start paused), `speed`
//! (playback rate, e.g. `0.5`), `yaw`, `pitch` (degrees), `distance` (metres) and `fov`
//! (degrees) override the camera, and `ui=0` hides the legend and the bar (the people alone, for
//! stills and contact sheets). The page also exposes `window.troupeViewer` with
//! `frames`, `fps`, `frame()`, `setFrame(n)`, `play()`, `pause()`, `camera()` and
//! `setCamera({yaw, pitch, distance, fov})`; `document.body.dataset.frame` is the frame shown.
//!
//! The data is embedded as JSON in a `<script type="application/json">` element: `title`,
//! `fps`, `frames`, `parents` (t2m-22, −1 for the root), `joints` (names), `unit` (metres per
//! position unit: 1e-4), `floor` (metres), `grid` (`[x0, x1, z0, z1, step]`, metres), `camera`
//! (`target`, `yaw`, `pitch`, `distance`, `fov`) and `people` (`name`, `colour` as `#rrggbb`,
//! `frames`, `positions`: `frames × 22 × 3` integers, canonical axes, in units of 0.1 mm). Every
//! `<` in it is written `\u003c`, so no text in it can close the element.

use std::path::Path;

use serde::Serialize;

use crate::motion::Skeleton;
use crate::shared::error::Result;
use crate::shared::files::write_atomically;
use crate::viewer::scene::Scene;

/// The page, with `{{TITLE}}`, `{{DRAW}}` and `{{DATA}}` to fill.
const TEMPLATE: &str = include_str!("player.html");
/// The drawing the player shares with the web page (web/), inlined into it.
const DRAW_JS: &str = include_str!("draw.js");

/// Metres per unit of the positions embedded in the page.
const POSITION_UNIT_M: f64 = 1e-4;

/// Spacing of the floor grid, metres.
const GRID_STEP_M: f32 = 0.5;

/// How far the floor grid reaches beyond the scene's joints, metres.
const GRID_MARGIN_M: f32 = 1.0;

#[derive(Serialize)]
struct Data<'a> {
    title: &'a str,
    fps: f32,
    frames: usize,
    parents: Vec<i32>,
    joints: &'a [String],
    unit: f64,
    floor: f32,
    grid: [f32; 5],
    camera: CameraData,
    people: Vec<PersonData<'a>>,
}

#[derive(Serialize)]
struct CameraData {
    target: [f32; 3],
    yaw: f32,
    pitch: f32,
    distance: f32,
    fov: f32,
}

#[derive(Serialize)]
struct PersonData<'a> {
    name: &'a str,
    colour: String,
    frames: usize,
    positions: Vec<i32>,
}

/// The floor grid of a scene: `[x0, x1, z0, z1, step]`, the scene's extent in x and z plus
/// [`GRID_MARGIN_M`], on multiples of [`GRID_STEP_M`].
pub(crate) fn grid(scene: &Scene) -> [f32; 5] {
    let (lo, hi) = scene
        .bounds()
        .unwrap_or(([-0.5, 0.0, -0.5], [0.5, 1.7, 0.5]));
    let down = |v: f32| ((v - GRID_MARGIN_M) / GRID_STEP_M).floor() * GRID_STEP_M;
    let up = |v: f32| ((v + GRID_MARGIN_M) / GRID_STEP_M).ceil() * GRID_STEP_M;
    [down(lo[0]), up(hi[0]), down(lo[2]), up(hi[2]), GRID_STEP_M]
}

/// Replaces `<`, `>` and `&` by JSON escapes (valid anywhere they can occur in JSON: inside
/// strings), so that the text is inert inside an HTML `<script>` element.
fn json_for_script(json: &str) -> String {
    json.replace('<', "\\u003c")
        .replace('>', "\\u003e")
        .replace('&', "\\u0026")
}

/// `text` as HTML character data.
fn escape_html(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// Fills the template's placeholders in one pass, so that no substituted text is read again.
fn fill(template: &str, values: &[(&str, &str)]) -> String {
    let mut out =
        String::with_capacity(template.len() + values.iter().map(|v| v.1.len()).sum::<usize>());
    let mut rest = template;
    while let Some(start) = rest.find("{{") {
        let hit = values.iter().find(|(key, _)| {
            rest[start + 2..].starts_with(key) && rest[start + 2 + key.len()..].starts_with("}}")
        });
        match hit {
            Some((key, value)) => {
                out.push_str(&rest[..start]);
                out.push_str(value);
                rest = &rest[start + 4 + key.len()..];
            }
            None => {
                out.push_str(&rest[..start + 2]);
                rest = &rest[start + 2..];
            }
        }
    }
    out.push_str(rest);
    out
}

impl Scene {
    /// The scene as a self-contained HTML player (see the [module documentation](self)).
    /// Fails only for a scene without people.
    pub fn to_html(&self) -> Result<String> {
        self.check_not_empty()?;
        let skeleton = Skeleton::t2m22();
        let camera = self.camera();
        let people = self
            .people()
            .iter()
            .map(|p| PersonData {
                name: p.name(),
                colour: p.colour_hex(),
                frames: p.frames(),
                positions: p
                    .positions()
                    .iter()
                    .map(|&v| (f64::from(v) / POSITION_UNIT_M).round() as i32)
                    .collect(),
            })
            .collect();
        let data = Data {
            title: self.title(),
            fps: self.fps(),
            frames: self.frames(),
            parents: skeleton
                .parents()
                .iter()
                .map(|p| p.map_or(-1, |p| p as i32))
                .collect(),
            joints: skeleton.names(),
            unit: POSITION_UNIT_M,
            floor: self.floor(),
            grid: grid(self),
            camera: CameraData {
                target: camera.target,
                yaw: camera.yaw_deg,
                pitch: camera.pitch_deg,
                distance: camera.distance,
                fov: camera.fov_deg,
            },
            people,
        };
        let json = serde_json::to_string(&data).expect("the data serialises");
        let title = if self.title().is_empty() {
            "troupe".to_string()
        } else {
            format!("{} · troupe", self.title())
        };
        Ok(fill(
            TEMPLATE,
            &[
                ("TITLE", &escape_html(&title)),
                ("DRAW", DRAW_JS),
                ("DATA", &json_for_script(&json)),
            ],
        ))
    }

    /// Writes [`Scene::to_html`] to `path`: through a temporary file beside it, renamed into
    /// place, so that nothing is written on error.
    pub fn write_html(&self, path: impl AsRef<Path>) -> Result<()> {
        let html = self.to_html()?;
        write_atomically(path.as_ref(), html.as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_are_filled_once() {
        let out = fill("a {{X}} b {{Y}} {{Z}}", &[("X", "{{Y}}"), ("Y", "y")]);
        assert_eq!(out, "a {{Y}} b y {{Z}}");
    }

    #[test]
    fn script_data_cannot_close_its_element() {
        let json = serde_json::to_string("</script><!--&").unwrap();
        let safe = json_for_script(&json);
        assert!(!safe.contains('<') && !safe.contains('>'));
        assert_eq!(
            serde_json::from_str::<String>(&safe).unwrap(),
            "</script><!--&"
        );
        assert_eq!(escape_html("<b>&\"'"), "&lt;b&gt;&amp;&quot;&#39;");
    }
}
