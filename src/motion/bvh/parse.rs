//! The BVH reader: a line-aware tokenizer, the hierarchy, and the motion block, with every size
//! bounded before it is allocated.

use std::path::Path;

use super::{Bvh, BvhJoint, Channel};
use crate::motion::features::MAX_CLIP_FRAMES;
use crate::shared::error::{excerpt, Error, Result};
use crate::shared::progress;

/// The largest BVH file troupe reads: 256 MiB (LAFAN1's longest take is about 10 MB).
pub const MAX_BVH_BYTES: u64 = 1 << 28;
/// The most joints a BVH hierarchy may have.
pub const MAX_BVH_JOINTS: usize = 1024;
/// The longest joint name, in bytes.
pub const MAX_BVH_NAME_BYTES: usize = 256;
/// The largest offset or position channel value, in the file's units (10 km in centimetres):
/// with at most [`MAX_BVH_JOINTS`] joints, every position forward kinematics gives is then
/// finite in `f32`.
pub const MAX_BVH_COORDINATE: f64 = 1e6;

#[derive(Clone, Copy)]
struct Token<'a> {
    text: &'a str,
    line: usize,
}

/// Whitespace-separated tokens with their line numbers, produced lazily so that the motion
/// block is never held twice.
struct Tokens<'a> {
    label: &'a str,
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    words: Option<(usize, std::str::SplitWhitespace<'a>)>,
    peeked: Option<Token<'a>>,
    last_line: usize,
}

impl<'a> Tokens<'a> {
    fn new(label: &'a str, text: &'a str) -> Self {
        Tokens {
            label,
            lines: text.lines().enumerate(),
            words: None,
            peeked: None,
            last_line: 0,
        }
    }

    fn pull(&mut self) -> Option<Token<'a>> {
        if let Some(t) = self.peeked.take() {
            return Some(t);
        }
        loop {
            if let Some((line, words)) = &mut self.words {
                if let Some(text) = words.next() {
                    self.last_line = *line;
                    return Some(Token { text, line: *line });
                }
            }
            let (i, line) = self.lines.next()?;
            self.words = Some((i + 1, line.split_whitespace()));
        }
    }

    fn peek_token(&mut self) -> Option<Token<'a>> {
        if self.peeked.is_none() {
            self.peeked = self.pull();
        }
        self.peeked
    }

    fn error(&self, line: usize, message: impl std::fmt::Display) -> Error {
        Error::InvalidInput(format!("{}:{line}: {message}", self.label))
    }

    fn line(&mut self) -> usize {
        self.peek_token().map_or(self.last_line, |t| t.line)
    }

    fn next(&mut self, what: &str) -> Result<Token<'a>> {
        let line = self.last_line;
        self.pull()
            .ok_or_else(|| self.error(line, format!("file ends where {what} was expected")))
    }

    fn expect(&mut self, word: &str) -> Result<usize> {
        let t = self.next(word)?;
        let (text, line) = (t.text, t.line);
        if !text.eq_ignore_ascii_case(word) {
            return Err(self.error(
                line,
                format!("expected `{word}`, found `{}`", excerpt(text)),
            ));
        }
        Ok(line)
    }

    fn number(&mut self, what: &str) -> Result<f64> {
        let t = self.next(what)?;
        let (text, line) = (t.text, t.line);
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.error(
                line,
                format!("{what}: `{}` is not a finite number", excerpt(text)),
            )),
        }
    }

    fn offset(&mut self, joint: &str) -> Result<[f64; 3]> {
        self.expect("OFFSET")?;
        let what = format!("OFFSET of {joint}");
        let mut offset = [0.0; 3];
        for v in &mut offset {
            let line = self.line();
            *v = self.number(&what)?;
            if v.abs() > MAX_BVH_COORDINATE {
                return Err(self.error(
                    line,
                    format!("{what}: {v} is beyond troupe's ±{MAX_BVH_COORDINATE}"),
                ));
            }
        }
        Ok(offset)
    }

    /// The rest of the current line up to a `{`: a joint's name (names may hold spaces).
    fn name(&mut self, keyword_line: usize) -> Result<String> {
        let mut parts = Vec::new();
        while let Some(t) = self.peek_token() {
            if t.line != keyword_line || t.text == "{" {
                break;
            }
            parts.push(t.text);
            self.peeked = None;
        }
        if parts.is_empty() {
            return Err(self.error(keyword_line, "a joint without a name"));
        }
        let name = parts.join(" ");
        if name.len() > MAX_BVH_NAME_BYTES || name.chars().any(char::is_control) {
            return Err(self.error(
                keyword_line,
                format!(
                    "joint name `{}`: names are at most {MAX_BVH_NAME_BYTES} bytes without \
                     control characters",
                    excerpt(&name)
                ),
            ));
        }
        Ok(name)
    }
}

/// Reads a BVH file from `path`, refusing anything that is not a regular file of at most
/// [`MAX_BVH_BYTES`] before reading it.
pub fn read_bvh(path: impl AsRef<Path>) -> Result<Bvh> {
    let path = path.as_ref();
    let bytes = crate::shared::files::read_bounded(path, MAX_BVH_BYTES, "BVH files")?;
    parse_bvh(&bytes, &path.display().to_string())
}

/// Parses BVH text (`label` names it in messages: a path or a description).
pub fn parse_bvh(bytes: &[u8], label: &str) -> Result<Bvh> {
    if bytes.len() as u64 > MAX_BVH_BYTES {
        return Err(Error::InvalidInput(format!(
            "{label}: {} bytes; troupe reads BVH files of at most {MAX_BVH_BYTES}",
            bytes.len()
        )));
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        Error::InvalidInput(format!(
            "{label}: not text (invalid UTF-8 at byte {})",
            e.valid_up_to()
        ))
    })?;
    let mut tokens = Tokens::new(label, text);
    tokens.expect("HIERARCHY")?;
    let joints = hierarchy(&mut tokens)?;
    motion(&mut tokens, joints, bytes.len())
}

fn hierarchy(tokens: &mut Tokens) -> Result<Vec<BvhJoint>> {
    let root_line = tokens.expect("ROOT")?;
    let mut joints: Vec<BvhJoint> = Vec::new();
    // The joints whose `{` is open, innermost last; an explicit stack, so that deep nesting
    // cannot overflow the call stack.
    let mut open: Vec<usize> = Vec::new();
    let mut pending = Some((root_line, None));
    loop {
        if let Some((line, parent)) = pending.take() {
            let name = tokens.name(line)?;
            if joints.len() == MAX_BVH_JOINTS {
                return Err(tokens.error(line, format!("more than {MAX_BVH_JOINTS} joints")));
            }
            if joints.iter().any(|j| j.name == name) {
                return Err(tokens.error(line, format!("joint `{name}` is defined twice")));
            }
            tokens.expect("{")?;
            let offset = tokens.offset(&name)?;
            tokens.expect("CHANNELS")?;
            let count_line = tokens.line();
            let count = tokens.number(&format!("CHANNELS count of {name}"))?;
            if !(0.0..=6.0).contains(&count) || count.fract() != 0.0 {
                return Err(tokens.error(
                    count_line,
                    format!("joint `{name}`: {count} channels; a joint has 0 to 6"),
                ));
            }
            let mut channels = Vec::with_capacity(count as usize);
            for _ in 0..count as usize {
                let t = tokens.next("a channel name")?;
                let (text, line) = (t.text, t.line);
                let c = Channel::parse(text).ok_or_else(|| {
                    tokens.error(
                        line,
                        format!(
                            "joint `{name}`: unknown channel `{}` (expected X/Y/Z position or \
                             rotation)",
                            excerpt(text)
                        ),
                    )
                })?;
                if channels.contains(&c) {
                    return Err(
                        tokens.error(line, format!("joint `{name}`: channel `{text}` twice"))
                    );
                }
                channels.push(c);
            }
            joints.push(BvhJoint {
                name,
                parent,
                offset,
                channels,
                end_site: None,
            });
            open.push(joints.len() - 1);
        }
        let Some(&current) = open.last() else {
            break;
        };
        let t = tokens.next("JOINT, End Site or }")?;
        let (text, line) = (t.text, t.line);
        match text {
            "}" => {
                open.pop();
            }
            t if t.eq_ignore_ascii_case("JOINT") => pending = Some((line, Some(current))),
            t if t.eq_ignore_ascii_case("End") => {
                tokens.expect("Site")?;
                tokens.expect("{")?;
                let name = format!("End Site of {}", joints[current].name);
                joints[current].end_site = Some(tokens.offset(&name)?);
                tokens.expect("}")?;
            }
            other => {
                return Err(tokens.error(
                    line,
                    format!(
                        "in joint `{}`: expected JOINT, End Site or }}, found `{}`",
                        joints[current].name,
                        excerpt(other)
                    ),
                ))
            }
        }
    }
    Ok(joints)
}

fn motion(tokens: &mut Tokens, joints: Vec<BvhJoint>, bytes_left: usize) -> Result<Bvh> {
    tokens.expect("MOTION")?;
    let line = tokens.expect("Frames:")?;
    let frames = tokens.number("the frame count")?;
    if frames < 0.0 || frames.fract() != 0.0 || frames > MAX_CLIP_FRAMES as f64 {
        return Err(tokens.error(
            line,
            format!("Frames: {frames}; troupe reads 0 to {MAX_CLIP_FRAMES} frames"),
        ));
    }
    let frames = frames as usize;
    let line = tokens.expect("Frame")?;
    tokens.expect("Time:")?;
    let frame_time = tokens.number("Frame Time")?;
    if frame_time <= 0.0 {
        return Err(tokens.error(line, format!("Frame Time {frame_time} is not positive")));
    }
    let per_frame: usize = joints.iter().map(|j| j.channels.len()).sum();
    // A value takes at least two bytes ("0 "), so the file's size bounds what is allocated.
    let total = frames.saturating_mul(per_frame);
    let mut values = Vec::with_capacity(total.min(bytes_left / 2 + 1));
    for f in 0..frames {
        // A long file can be stopped: progress every 4096 frames.
        if f % 4096 == 4095 {
            progress::report("reading the BVH", f as u64 + 1, frames as u64)?;
        }
        for joint in &joints {
            for c in &joint.channels {
                let Some(t) = tokens.pull() else {
                    return Err(tokens.error(
                        tokens.last_line,
                        format!(
                            "Frames: {frames}, but the file ends in frame {f} (at joint `{}`): \
                             truncated?",
                            joint.name
                        ),
                    ));
                };
                let position = c.rotation_axis().is_none();
                match t.text.parse::<f32>() {
                    Ok(v) if position && f64::from(v.abs()) > MAX_BVH_COORDINATE => {
                        return Err(tokens.error(
                            t.line,
                            format!(
                                "frame {f}, joint `{}`, {}: {v} is beyond troupe's \
                                 ±{MAX_BVH_COORDINATE}",
                                joint.name,
                                c.name()
                            ),
                        ))
                    }
                    Ok(v) if v.is_finite() => values.push(v),
                    _ => {
                        return Err(tokens.error(
                            t.line,
                            format!(
                                "frame {f}, joint `{}`, {}: `{}` is not a finite number",
                                joint.name,
                                c.name(),
                                excerpt(t.text)
                            ),
                        ))
                    }
                }
            }
        }
    }
    if let Some(t) = tokens.pull() {
        return Err(tokens.error(
            t.line,
            format!(
                "`{}` after the {frames} frames the file declares",
                excerpt(t.text)
            ),
        ));
    }
    Ok(Bvh {
        joints,
        frame_time,
        values,
        channels_per_frame: per_frame,
    })
}
