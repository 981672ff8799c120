//! Pictures a person can look at: a [`Scene`] of people moving on the t2m-22 skeleton, written
//! as a self-contained HTML player or an animated GIF.
//!
//! A layer beside [`crate::motion`]: it imports only `crate::shared` and [`crate::motion`],
//! and no model family.
//!
//! - [`scene`]: the data (people × frames × 22 joints in canonical y-up metres, frame rate,
//!   names, colours, title), validated;
//! - [`camera`]: the perspective camera both pictures share, and the default framing of a scene;
//! - [`html`]: one HTML file with the data and a small JavaScript player inlined (no network);
//! - [`animation`]: the animated GIF, rendered in Rust;
//! - `raster`: the line and disk rasteriser beneath the GIF.
//!
//! Files are written through a temporary file renamed into place (`shared::files`), so that
//! nothing is left behind on error.
//!
//! ```no_run
//! use ndarray::Array3;
//! use troupe::viewer::{GifOptions, Scene};
//!
//! let actor = Array3::<f32>::zeros((30, 22, 3)); // [frames][22][3], metres, +Y up
//! let mut scene = Scene::new(30.0, "a reaction")?;
//! scene.add_person("actor", actor.view())?;
//! scene.write_html("reaction.html")?;
//! scene.write_gif("reaction.gif", &GifOptions::default())?;
//! # Ok::<(), troupe::Error>(())
//! ```

pub mod animation;
pub mod camera;
pub mod html;
mod raster;
pub mod scene;

use std::path::Path;

use crate::shared::error::Result;
use crate::shared::files::Pending;

pub use animation::GifOptions;
pub use camera::Camera;
pub use scene::{Person, Scene, MAX_FRAMES, MAX_NAME_CHARS, MAX_PEOPLE, MAX_TITLE_CHARS, PALETTE};

impl Scene {
    /// Writes the HTML player to `html` and the GIF (drawn with `gif_options`) to `gif`, either
    /// of which may be `None`: both are rendered and written to temporary files first, then
    /// renamed into place, so that on error neither is written. (A rename needs no space; should
    /// the second fail all the same, say because its directory was removed meanwhile, the
    /// first file stays in place and the error names the second.)
    pub fn write_pictures(
        &self,
        html: Option<&Path>,
        gif: Option<&Path>,
        gif_options: &GifOptions,
    ) -> Result<()> {
        let html_bytes = html.map(|_| self.to_html()).transpose()?;
        let gif_bytes = gif.map(|_| self.to_gif(gif_options)).transpose()?;
        let mut pending = Vec::new();
        if let (Some(path), Some(bytes)) = (html, &html_bytes) {
            pending.push(Pending::write(path, bytes.as_bytes())?);
        }
        if let (Some(path), Some(bytes)) = (gif, &gif_bytes) {
            pending.push(Pending::write(path, bytes)?);
        }
        for p in pending {
            p.commit()?;
        }
        Ok(())
    }
}
