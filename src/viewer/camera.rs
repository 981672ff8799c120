//! The perspective camera the HTML player and the GIF share. The player's JavaScript does the
//! same arithmetic as [`Camera::project`], so a test can say where on the screen a joint lands.
//!
//! The camera orbits a target point: it sits `distance` metres away, `yaw_deg` degrees around
//! the vertical from the +Z side (0: on the +Z axis looking toward −Z, so that +X is to the
//! right of the picture; positive yaw moves it toward +X), `pitch_deg` degrees above the
//! horizontal, looking at the target with +Y up. `fov_deg` is the field of view across the
//! shorter side of the picture.

/// An orbiting perspective camera (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// The point looked at, canonical axes, metres.
    pub target: [f32; 3],
    /// Turn about +Y from the +Z side, degrees.
    pub yaw_deg: f32,
    /// Elevation above the horizontal, degrees, in (−90, 90).
    pub pitch_deg: f32,
    /// Distance from the target, metres.
    pub distance: f32,
    /// Field of view across the shorter side of the picture, degrees.
    pub fov_deg: f32,
}

/// Points nearer the camera than this (metres, along its axis) are not drawn.
pub const NEAR_M: f32 = 0.05;

/// Yaw of [`Camera::framing`]: from the front, a little to the side.
const DEFAULT_YAW_DEG: f32 = 25.0;
/// Pitch of [`Camera::framing`]: a little above.
const DEFAULT_PITCH_DEG: f32 = 12.0;
/// Field of view of [`Camera::framing`].
const DEFAULT_FOV_DEG: f32 = 40.0;

impl Camera {
    /// The default camera for a box of joints `(lo, hi)`: looking at its centre from the front
    /// and a little to the side and above (yaw 25°, pitch 12°) with a 40° field of view, from
    /// the distance at which a sphere around the box (half its diagonal, at least 0.9 m) just
    /// fits the field of view.
    pub fn framing(lo: [f32; 3], hi: [f32; 3]) -> Camera {
        let target = std::array::from_fn(|d| 0.5 * (lo[d] + hi[d]));
        let half_diagonal = 0.5
            * (0..3)
                .map(|d| (hi[d] - lo[d]) * (hi[d] - lo[d]))
                .sum::<f32>()
                .sqrt();
        let radius = half_diagonal.max(0.9);
        let half_fov = (0.5 * DEFAULT_FOV_DEG).to_radians();
        Camera {
            target,
            yaw_deg: DEFAULT_YAW_DEG,
            pitch_deg: DEFAULT_PITCH_DEG,
            distance: radius / half_fov.sin(),
            fov_deg: DEFAULT_FOV_DEG,
        }
    }

    /// The camera's basis: its position, right, up and forward unit vectors.
    fn basis(&self) -> [[f32; 3]; 4] {
        let (yaw, pitch) = (self.yaw_deg.to_radians(), self.pitch_deg.to_radians());
        let back = [
            pitch.cos() * yaw.sin(),
            pitch.sin(),
            pitch.cos() * yaw.cos(),
        ];
        let eye = std::array::from_fn(|d| self.target[d] + self.distance * back[d]);
        let forward = back.map(|v| -v);
        let right = [yaw.cos(), 0.0, -yaw.sin()];
        // up = right × forward
        let up = [
            right[1] * forward[2] - right[2] * forward[1],
            right[2] * forward[0] - right[0] * forward[2],
            right[0] * forward[1] - right[1] * forward[0],
        ];
        [eye, right, up, forward]
    }

    /// Where the camera is.
    pub fn eye(&self) -> [f32; 3] {
        self.basis()[0]
    }

    /// `p` in camera coordinates: `[right, up, depth]`, metres.
    pub fn to_camera(&self, p: [f32; 3]) -> [f32; 3] {
        let [eye, right, up, forward] = self.basis();
        let d: [f32; 3] = std::array::from_fn(|i| p[i] - eye[i]);
        let dot = |a: [f32; 3]| a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
        [dot(right), dot(up), dot(forward)]
    }

    /// Pixels per metre at one metre's depth in a `width` × `height` picture.
    pub fn focal_px(&self, width: f32, height: f32) -> f32 {
        0.5 * width.min(height) / (0.5 * self.fov_deg.to_radians()).tan()
    }

    /// A point in camera coordinates ([`Camera::to_camera`]) on a `width` × `height` picture:
    /// `[x, y]` in pixels from the top-left corner, or `None` nearer than [`NEAR_M`].
    pub fn project_camera(&self, c: [f32; 3], width: f32, height: f32) -> Option<[f32; 2]> {
        if c[2] < NEAR_M {
            return None;
        }
        let f = self.focal_px(width, height);
        Some([
            0.5 * width + f * c[0] / c[2],
            0.5 * height - f * c[1] / c[2],
        ])
    }

    /// Where `p` (canonical axes, metres) lands on a `width` × `height` picture: pixels from
    /// the top-left corner, or `None` when it is nearer than [`NEAR_M`] or behind the camera.
    pub fn project(&self, p: [f32; 3], width: f32, height: f32) -> Option<[f32; 2]> {
        self.project_camera(self.to_camera(p), width, height)
    }

    /// The segment `a`–`b` on the picture, cut where it passes nearer than [`NEAR_M`], or
    /// `None` when all of it is.
    pub fn project_segment(
        &self,
        a: [f32; 3],
        b: [f32; 3],
        width: f32,
        height: f32,
    ) -> Option<([f32; 2], [f32; 2])> {
        let (mut ca, mut cb) = (self.to_camera(a), self.to_camera(b));
        if ca[2] < NEAR_M && cb[2] < NEAR_M {
            return None;
        }
        let cut = |from: [f32; 3], to: [f32; 3]| {
            let s = (NEAR_M - from[2]) / (to[2] - from[2]);
            std::array::from_fn(|d| from[d] + s * (to[d] - from[d]))
        };
        if ca[2] < NEAR_M {
            ca = cut(ca, cb);
        } else if cb[2] < NEAR_M {
            cb = cut(cb, ca);
        }
        Some((
            self.project_camera(ca, width, height)?,
            self.project_camera(cb, width, height)?,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_front_camera_puts_plus_x_right_and_up_up() {
        let cam = Camera {
            target: [0.0, 1.0, 0.0],
            yaw_deg: 0.0,
            pitch_deg: 0.0,
            distance: 4.0,
            fov_deg: 40.0,
        };
        assert_eq!(cam.eye(), [0.0, 1.0, 4.0]);
        let c = cam.project([0.0, 1.0, 0.0], 800.0, 600.0).unwrap();
        assert!((c[0] - 400.0).abs() < 1e-3 && (c[1] - 300.0).abs() < 1e-3);
        let right = cam.project([1.0, 1.0, 0.0], 800.0, 600.0).unwrap();
        let up = cam.project([0.0, 2.0, 0.0], 800.0, 600.0).unwrap();
        assert!(right[0] > 400.0 && up[1] < 300.0);
        assert!(cam.project([0.0, 1.0, 5.0], 800.0, 600.0).is_none());
        let (a, b) = cam
            .project_segment([0.0, 1.0, 0.0], [0.0, 1.0, 10.0], 800.0, 600.0)
            .unwrap();
        assert_eq!(a, c);
        assert!(b[0].is_finite() && b[1].is_finite());
    }

    #[test]
    fn framing_fits_the_box() {
        let cam = Camera::framing([-1.0, 0.0, -0.5], [1.0, 1.8, 0.5]);
        for corner in [[-1.0, 0.0, -0.5], [1.0, 1.8, 0.5], [1.0, 0.0, 0.5]] {
            let p = cam.project(corner, 800.0, 600.0).unwrap();
            assert!(
                (0.0..800.0).contains(&p[0]) && (0.0..600.0).contains(&p[1]),
                "{p:?}"
            );
        }
    }
}
