//! Pictures as a person sees them: headless Chromium screenshots of the HTML player, PNG
//! decoding, and the camera's projection written again from its documented definition, so that
//! tests can check each person's colour is where their joints project.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use troupe::motion::Skeleton;
use troupe::viewer::{Camera, Scene};

/// The first person's colour in the player and the GIF.
pub const BLUE: [u8; 3] = [0x1f, 0x77, 0xb4];
/// The second person's colour.
pub const ORANGE: [u8; 3] = [0xff, 0x7f, 0x0e];

// ---------------------------------------------------------------------------------------------
// The projection, from the camera's documented definition (src/viewer/camera.rs): the eye sits
// `distance` from the target at `yaw` about +Y from +Z and `pitch` above the horizontal; the
// field of view spans the shorter side of the picture.

pub fn project(cam: &Camera, p: [f32; 3], w: f64, h: f64) -> Option<[f64; 2]> {
    let (yaw, pitch) = (
        f64::from(cam.yaw_deg).to_radians(),
        f64::from(cam.pitch_deg).to_radians(),
    );
    let target = cam.target.map(f64::from);
    let dist = f64::from(cam.distance);
    let eye = [
        target[0] + dist * pitch.cos() * yaw.sin(),
        target[1] + dist * pitch.sin(),
        target[2] + dist * pitch.cos() * yaw.cos(),
    ];
    let unit = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / n)
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let forward = unit([target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]]);
    let right = unit(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    let d = [
        f64::from(p[0]) - eye[0],
        f64::from(p[1]) - eye[1],
        f64::from(p[2]) - eye[2],
    ];
    let depth = dot(d, forward);
    if depth < 0.05 {
        return None;
    }
    let focal = 0.5 * w.min(h) / (0.5 * f64::from(cam.fov_deg).to_radians()).tan();
    Some([
        0.5 * w + focal * dot(d, right) / depth,
        0.5 * h - focal * dot(d, up) / depth,
    ])
}

// ---------------------------------------------------------------------------------------------
// Pictures as pixels.

pub struct Image {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[u8; 3]>,
}

impl Image {
    pub fn at(&self, x: i64, y: i64) -> Option<[u8; 3]> {
        (x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height)
            .then(|| self.rgb[y as usize * self.width + x as usize])
    }

    /// Pixels of (nearly) `colour`.
    pub fn matching(&self, colour: [u8; 3]) -> Vec<[f64; 2]> {
        (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .filter(|&(x, y)| close(self.rgb[y * self.width + x], colour))
            .map(|(x, y)| [x as f64 + 0.5, y as f64 + 0.5])
            .collect()
    }
}

pub fn close(a: [u8; 3], b: [u8; 3]) -> bool {
    (0..3)
        .map(|d| (i32::from(a[d]) - i32::from(b[d])).abs())
        .sum::<i32>()
        <= 60
}

pub fn decode_png(path: &Path) -> Image {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Eight, "{path:?}");
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("{path:?}: unexpected colour type {other:?}"),
    };
    let (width, height) = (info.width as usize, info.height as usize);
    let rgb = buffer[..width * height * channels]
        .chunks_exact(channels)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    Image { width, height, rgb }
}

/// What a picture shows of one person at one frame, given where its joints project.
pub struct Seen {
    /// Joints with a pixel of the person's colour within the search radius.
    pub joints_found: usize,
    /// Pixels of the colour left of the middle.
    pub left: usize,
    /// Pixels of the colour right of the middle.
    pub right: usize,
    /// Pixels of the colour farther than 25 px from every projected bone (the head's disk
    /// reaches about 20 px from its joint).
    pub stray: usize,
    /// Mean position of the colour's pixels.
    pub centroid: [f64; 2],
}

pub fn see(image: &Image, colour: [u8; 3], joints: &[[f64; 2]], radius: i64) -> Seen {
    let joints_found = joints
        .iter()
        .filter(|p| {
            let (cx, cy) = (p[0].floor() as i64, p[1].floor() as i64);
            (-radius..=radius).any(|dy| {
                (-radius..=radius)
                    .any(|dx| image.at(cx + dx, cy + dy).is_some_and(|c| close(c, colour)))
            })
        })
        .count();
    let pixels = image.matching(colour);
    let middle = image.width as f64 / 2.0;
    let parents = Skeleton::t2m22().parents().to_vec();
    let near_bone = |q: [f64; 2]| {
        parents.iter().enumerate().any(|(j, p)| {
            let (a, b) = (joints[p.unwrap_or(j)], joints[j]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let l2 = (dx * dx + dy * dy).max(1e-9);
            let s = (((q[0] - a[0]) * dx + (q[1] - a[1]) * dy) / l2).clamp(0.0, 1.0);
            let (ex, ey) = (q[0] - a[0] - s * dx, q[1] - a[1] - s * dy);
            ex * ex + ey * ey < 25.0 * 25.0
        })
    };
    let n = pixels.len().max(1) as f64;
    Seen {
        joints_found,
        left: pixels.iter().filter(|p| p[0] < middle).count(),
        right: pixels.iter().filter(|p| p[0] >= middle).count(),
        stray: pixels.iter().filter(|&&q| !near_bone(q)).count(),
        centroid: [
            pixels.iter().map(|p| p[0]).sum::<f64>() / n,
            pixels.iter().map(|p| p[1]).sum::<f64>() / n,
        ],
    }
}

pub fn projected(
    scene: &Scene,
    person: usize,
    t: usize,
    cam: &Camera,
    image: &Image,
) -> Vec<[f64; 2]> {
    let pose = scene.people()[person].pose(t);
    (0..22)
        .map(|j| {
            project(
                cam,
                [pose[[j, 0]], pose[[j, 1]], pose[[j, 2]]],
                image.width as f64,
                image.height as f64,
            )
            .expect("every joint is in front of the camera")
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Chromium.

/// The Chromium binary: `TROUPE_CHROMIUM`, else `chromium` on `PATH`; a failing test without.
pub fn chromium() -> PathBuf {
    if let Some(path) = std::env::var_os("TROUPE_CHROMIUM") {
        return PathBuf::from(path);
    }
    for name in ["chromium", "chromium-browser"] {
        for dir in std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()) {
            let candidate = dir.join(name);
            if candidate.is_file() {
                return candidate;
            }
        }
    }
    panic!(
        "Chromium is needed to test the HTML viewer and was not found on PATH: install Debian's \
         `chromium` package (`apt-get install --no-install-recommends chromium`, as .ci/run does) \
         or set TROUPE_CHROMIUM to a Chromium or Chrome binary"
    );
}

/// A screenshot of `html` with `query` in an 800 × 600 window.
pub fn screenshot(html: &Path, query: &str, out: &Path) -> Image {
    let url = format!(
        "file://{}?{query}",
        html.display().to_string().replace(' ', "%20")
    );
    let name = query.replace(['&', '='], "_");
    screenshot_url(&url, &[], out, &name)
}

/// A screenshot of `url` in an 800 × 600 window (`flags` added to Chromium's); `name` is the
/// file name `TROUPE_VIEWER_KEEP` keeps it under.
pub fn screenshot_url(url: &str, flags: &[&str], out: &Path, name: &str) -> Image {
    let screenshot = format!("--screenshot={}", out.display());
    let mut args = flags.to_vec();
    args.push(&screenshot);
    run_chromium(url, &args);
    assert!(out.is_file(), "chromium wrote no screenshot of {url}");
    if let Some(keep) = std::env::var_os("TROUPE_VIEWER_KEEP") {
        let _ = std::fs::copy(out, Path::new(&keep).join(format!("{name}.png")));
    }
    decode_png(out)
}

/// The DOM of `url` once its scripts have run (Chromium's `--dump-dom`).
pub fn dump_dom(url: &str, flags: &[&str]) -> String {
    let mut args = flags.to_vec();
    args.push("--dump-dom");
    run_chromium(url, &args)
}

/// Runs headless Chromium on `url` with troupe's flags and `extra`; its stdout.
fn run_chromium(url: &str, extra: &[&str]) -> String {
    let profile = tempfile::tempdir().unwrap();
    let mut child = Command::new(chromium())
        .args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-first-run",
            "--no-default-browser-check",
            "--disable-extensions",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
            "--window-size=800,600",
            "--virtual-time-budget=3000",
        ])
        .args(extra)
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg(url)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run {:?}: {e}", chromium()));
    // Read both pipes while it runs: a full pipe would stall it.
    let mut stdout_pipe = child.stdout.take().unwrap();
    let mut stderr_pipe = child.stderr.take().unwrap();
    use std::io::Read;
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stdout_pipe.read_to_string(&mut text);
        text
    });
    let errors = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr_pipe.read_to_string(&mut text);
        text
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("chromium took over 60 s on {url}");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let stdout = reader.join().unwrap();
    let stderr = errors.join().unwrap();
    assert!(
        status.success(),
        "chromium failed on {url} ({status}):\n{stderr}"
    );
    stdout
}
