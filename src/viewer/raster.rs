//! A small rasteriser into palette indices: thick anti-aliased segments and disks.
//!
//! Anti-aliasing has three levels: each person has three palette entries, their colour blended
//! over the background at 1/3, 2/3 and full strength, and a pixel takes the level nearest its
//! coverage. A person's pixel is replaced by a stronger one of the same person, or by any
//! other person's pixel at least as strong (people are drawn farthest first).

/// Palette index of the background.
pub(crate) const BACKGROUND: u8 = 0;
/// Palette index of the floor grid.
pub(crate) const GRID: u8 = 1;
/// Palette index of the first person's faintest level; person `p`, level `l` (1 to 3) is at
/// `PEOPLE + 3 p + l - 1`.
pub(crate) const PEOPLE: u8 = 2;

/// Background colour (the HTML player's too).
pub(crate) const BACKGROUND_RGB: [u8; 3] = [0xf4, 0xf4, 0xf2];
/// Floor grid colour (the HTML player's too).
pub(crate) const GRID_RGB: [u8; 3] = [0xcf, 0xcf, 0xcf];

/// The palette for people of the given colours, `[r, g, b, ...]`.
pub(crate) fn palette(colours: &[[u8; 3]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(3 * (2 + 3 * colours.len()));
    out.extend_from_slice(&BACKGROUND_RGB);
    out.extend_from_slice(&GRID_RGB);
    for colour in colours {
        for level in 1..=3u16 {
            for d in 0..3 {
                let (bg, c) = (u16::from(BACKGROUND_RGB[d]), u16::from(colour[d]));
                out.push(((bg * (3 - level) + c * level + 1) / 3) as u8);
            }
        }
    }
    out
}

/// A box of pixels: `(x, y, width, height)`.
pub(crate) type Area = (usize, usize, usize, usize);

/// What a shape is drawn with.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Ink {
    /// One palette index, set where coverage is at least one half.
    Solid(u8),
    /// Person `p`'s colour, anti-aliased.
    Person(u8),
}

/// An image of palette indices, row-major.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Raster {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u8>,
}

impl Raster {
    /// A `width` × `height` image of the background.
    pub(crate) fn new(width: usize, height: usize) -> Raster {
        Raster {
            width,
            height,
            pixels: vec![BACKGROUND; width * height],
        }
    }

    fn put(&mut self, x: usize, y: usize, coverage: f32, ink: Ink) {
        let at = y * self.width + x;
        match ink {
            Ink::Solid(index) => {
                if coverage >= 0.5 {
                    self.pixels[at] = index;
                }
            }
            Ink::Person(p) => {
                let level = (coverage * 3.0).round().clamp(0.0, 3.0) as u8;
                if level == 0 {
                    return;
                }
                let old = self.pixels[at];
                let replace = if old < PEOPLE {
                    true
                } else {
                    let (q, old_level) = ((old - PEOPLE) / 3, (old - PEOPLE) % 3 + 1);
                    if q == p {
                        level > old_level
                    } else {
                        level >= old_level
                    }
                };
                if replace {
                    self.pixels[at] = PEOPLE + 3 * p + level - 1;
                }
            }
        }
    }

    /// Pixels whose centres lie within `reach` of the box `lo`–`hi`, clamped to the image:
    /// `(x0, x1, y0, y1)`, end-exclusive, or `None` when off the image.
    fn window(
        &self,
        lo: [f32; 2],
        hi: [f32; 2],
        reach: f32,
    ) -> Option<(usize, usize, usize, usize)> {
        let (w, h) = (self.width as f32, self.height as f32);
        let x0 = (lo[0] - reach - 0.5).floor().max(0.0);
        let y0 = (lo[1] - reach - 0.5).floor().max(0.0);
        let x1 = (hi[0] + reach + 0.5).ceil().min(w);
        let y1 = (hi[1] + reach + 0.5).ceil().min(h);
        (x0 < x1 && y0 < y1 && x1.is_finite() && y1.is_finite()).then_some((
            x0 as usize,
            x1 as usize,
            y0 as usize,
            y1 as usize,
        ))
    }

    /// A segment `a`–`b`, `width` pixels wide with round ends.
    pub(crate) fn segment(&mut self, a: [f32; 2], b: [f32; 2], width: f32, ink: Ink) {
        let half = 0.5 * width;
        let lo = [a[0].min(b[0]), a[1].min(b[1])];
        let hi = [a[0].max(b[0]), a[1].max(b[1])];
        let Some((x0, x1, y0, y1)) = self.window(lo, hi, half + 1.0) else {
            return;
        };
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let length2 = dx * dx + dy * dy;
        for y in y0..y1 {
            for x in x0..x1 {
                let (px, py) = (x as f32 + 0.5 - a[0], y as f32 + 0.5 - a[1]);
                let s = if length2 > 0.0 {
                    ((px * dx + py * dy) / length2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (ex, ey) = (px - s * dx, py - s * dy);
                let distance = (ex * ex + ey * ey).sqrt();
                let coverage = (half + 0.5 - distance).clamp(0.0, 1.0);
                if coverage > 0.0 {
                    self.put(x, y, coverage, ink);
                }
            }
        }
    }

    /// A filled disk of `radius` pixels around `c`.
    pub(crate) fn disk(&mut self, c: [f32; 2], radius: f32, ink: Ink) {
        let Some((x0, x1, y0, y1)) = self.window(c, c, radius + 1.0) else {
            return;
        };
        for y in y0..y1 {
            for x in x0..x1 {
                let (px, py) = (x as f32 + 0.5 - c[0], y as f32 + 0.5 - c[1]);
                let coverage = (radius + 0.5 - (px * px + py * py).sqrt()).clamp(0.0, 1.0);
                if coverage > 0.0 {
                    self.put(x, y, coverage, ink);
                }
            }
        }
    }

    /// The smallest box `(x, y, width, height)` holding every pixel that differs from
    /// `other`'s, or `None` when none does.
    pub(crate) fn changed_box(&self, other: &Raster) -> Option<Area> {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in 0..self.height {
            let row = y * self.width..(y + 1) * self.width;
            let (mine, theirs) = (&self.pixels[row.clone()], &other.pixels[row]);
            if mine == theirs {
                continue;
            }
            let first = mine
                .iter()
                .zip(theirs)
                .position(|(a, b)| a != b)
                .unwrap_or(0);
            let last = mine
                .iter()
                .zip(theirs)
                .rposition(|(a, b)| a != b)
                .unwrap_or(0);
            x0 = x0.min(first);
            x1 = x1.max(last + 1);
            y0 = y0.min(y);
            y1 = y + 1;
        }
        (x1 > 0).then(|| (x0, y0, x1 - x0, y1 - y0))
    }

    /// The pixels of the box `(x, y, width, height)`, row-major.
    pub(crate) fn crop(&self, (x, y, w, h): Area) -> Vec<u8> {
        let mut out = Vec::with_capacity(w * h);
        for row in y..y + h {
            out.extend_from_slice(&self.pixels[row * self.width + x..row * self.width + x + w]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_are_thick_and_soft_at_the_edge_and_boxes_find_changes() {
        let mut r = Raster::new(40, 20);
        let blank = r.clone();
        r.segment([5.0, 10.5], [35.0, 10.5], 3.0, Ink::Person(1));
        let full = PEOPLE + 3 + 2;
        let column: Vec<u8> = (0..20).map(|y| r.pixels[y * 40 + 20]).collect();
        assert_eq!(&column[8..13], &[BACKGROUND, full, full, full, BACKGROUND]);
        // Half-covered pixels take the middle level.
        r.segment([5.0, 3.0], [35.0, 3.0], 3.0, Ink::Person(1));
        assert_eq!(r.pixels[4 * 40 + 20], PEOPLE + 3 + 1);
        let (x, y, w, h) = r.changed_box(&blank).unwrap();
        assert!(
            x <= 5 && x + w >= 35 && y <= 2 && y + h >= 12,
            "{x} {y} {w} {h}"
        );
        assert_eq!(r.crop((x, y, w, h)).len(), w * h);
        assert_eq!(blank.changed_box(&blank), None);
        // A fainter pixel of another person does not cover a full one.
        r.disk([20.5, 10.5], 0.2, Ink::Person(0));
        assert_eq!(r.pixels[10 * 40 + 20], full);
        assert_eq!(palette(&[[0, 0, 0]]).len(), 3 * 5);
    }
}
