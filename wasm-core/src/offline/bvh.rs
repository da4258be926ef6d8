//! BVH (Biovision Hierarchy) import: text → skeleton + per-frame channel values.
//!
//! Accepts what real exporters write: any of the 6 Euler orders per joint, position channels
//! on any joint (each present component *replaces* that component of the joint's OFFSET, as
//! Blender and MotionBuilder read them), `End Site` blocks, CRLF line ends, tabs, names with
//! spaces, a UTF-8 byte-order mark, CR-only line ends. Anything else is an [`Error::Bvh`]
//! naming the line and what was expected. Untrusted input is bounded by [`crate::limits`]:
//! joint count, nesting depth, name length, frame count, frame time and value magnitude.

use crate::error::{Error, Result};
use crate::limits::{
    quote, MAX_ABS_BVH_VALUE, MAX_DEPTH, MAX_FRAMES, MAX_FRAME_TIME, MAX_JOINTS, MAX_NAME_BYTES, MIN_FRAME_TIME,
};
use glam::{DQuat, DVec3};
use std::borrow::Cow;

/// One animated degree of freedom of a joint, in file order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    PosX,
    PosY,
    PosZ,
    RotX,
    RotY,
    RotZ,
}

impl Channel {
    fn from_name(name: &str) -> Option<Channel> {
        Some(match name.to_ascii_lowercase().as_str() {
            "xposition" => Channel::PosX,
            "yposition" => Channel::PosY,
            "zposition" => Channel::PosZ,
            "xrotation" => Channel::RotX,
            "yrotation" => Channel::RotY,
            "zrotation" => Channel::RotZ,
            _ => return None,
        })
    }
}

/// A joint of the BVH hierarchy.
#[derive(Clone, Debug)]
pub struct BvhJoint {
    pub name: String,
    /// Index of the parent joint, `None` for the root. Parents precede children.
    pub parent: Option<usize>,
    /// Rest position in the parent's space (file units).
    pub offset: DVec3,
    pub channels: Vec<Channel>,
    /// Index of this joint's first channel within a frame's values.
    pub first_channel: usize,
    /// Offset of the `End Site` child, if the joint has one (file units).
    pub end_site: Option<DVec3>,
}

/// A parsed BVH file. Motion values are kept as written (degrees, file units).
#[derive(Clone, Debug)]
pub struct Bvh {
    pub joints: Vec<BvhJoint>,
    pub num_channels: usize,
    pub num_frames: usize,
    /// Seconds per frame (`Frame Time`).
    pub frame_time: f64,
    /// `num_frames × num_channels` values, frame-major.
    pub values: Vec<f64>,
    /// Roles the file itself names, `(role, joint name)`: a VRM humanoid map of a glTF take
    /// (`crate::gltf`); none for BVH. A build config's `roles` take precedence.
    pub role_hints: Vec<(String, String)>,
}

impl Bvh {
    /// Parses BVH text. `file` only names the input in error messages.
    ///
    /// Accepts a UTF-8 byte-order mark and CR-only (classic Mac) line ends as well as LF and
    /// CRLF. Buffers are sized from the bytes present, never from `Frames:`, and the hierarchy
    /// is read without recursion, so any input parses in time and memory linear in its size
    /// (at most [`BVH_ALLOCATION_FACTOR`](crate::limits::BVH_ALLOCATION_FACTOR) × its length
    /// + 1 MiB).
    ///
    /// # Errors
    /// [`Error::Bvh`] naming the file and line when the text is not a BVH file this importer
    /// reads, including when it exceeds a limit of [`crate::limits`]: more than
    /// [`MAX_JOINTS`] joints, nesting deeper than [`MAX_DEPTH`], a name longer than
    /// [`MAX_NAME_BYTES`], `Frames:` not a whole number in `0..=`[`MAX_FRAMES`], `Frame Time:`
    /// outside [`MIN_FRAME_TIME`]…[`MAX_FRAME_TIME`] s, or any number that is not finite or
    /// exceeds [`MAX_ABS_BVH_VALUE`] in magnitude. UTF-16/32 text is refused with a message
    /// saying so.
    pub fn parse(file: &str, bytes: &[u8]) -> Result<Bvh> {
        // A UTF-8 byte-order mark is invisible in editors; accept it rather than report
        // "expected 'HIERARCHY', found 'HIERARCHY'".
        let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        if let Some(encoding) = wide_encoding(bytes) {
            return Err(Error::bvh(file, 1, format!("the file is {encoding} text; save it as UTF-8 or ASCII")));
        }
        // Valid UTF-8 is borrowed as is (fast validation); otherwise exotic (Latin-1) joint
        // names are kept readable with replacement characters.
        let mut text = match std::str::from_utf8(bytes) {
            Ok(t) => Cow::Borrowed(t),
            Err(_) => String::from_utf8_lossy(bytes),
        };
        // CR-only line ends (classic Mac): without this the whole file is "line 1" and the
        // frame count reads as end of file. memchr-fast, and only such files pay for a copy.
        if !text.as_bytes().contains(&b'\n') && text.as_bytes().contains(&b'\r') {
            text = Cow::Owned(text.replace('\r', "\n"));
        }
        Parser { file, text: &text, pos: 0, line: 1 }.parse()
    }

    /// Heap bytes this parse holds: the values, the joints and their names and channels.
    pub fn heap_bytes(&self) -> usize {
        self.values.capacity() * std::mem::size_of::<f64>()
            + self.joints.capacity() * std::mem::size_of::<BvhJoint>()
            + self
                .joints
                .iter()
                .map(|j| j.name.capacity() + j.channels.capacity() * std::mem::size_of::<Channel>())
                .sum::<usize>()
    }

    /// Frames per second (`1 / Frame Time`).
    pub fn fps(&self) -> f64 {
        1.0 / self.frame_time
    }

    /// Channel values of one frame.
    ///
    /// # Panics
    /// If `frame >= num_frames`.
    pub fn frame(&self, frame: usize) -> &[f64] {
        &self.values[frame * self.num_channels..(frame + 1) * self.num_channels]
    }

    /// Local translation and rotation of `joint` at `frame`: the Euler channels composed in
    /// file order (first listed = outermost, `R = R₁·R₂·R₃`), position channels replacing the
    /// offset's components.
    ///
    /// # Panics
    /// If `frame >= num_frames` or `joint >= joints.len()`.
    pub fn local_transform(&self, frame: usize, joint: usize) -> (DVec3, DQuat) {
        let j = &self.joints[joint];
        let values = &self.frame(frame)[j.first_channel..j.first_channel + j.channels.len()];
        let mut translation = j.offset;
        let mut rotation = DQuat::IDENTITY;
        for (&channel, &v) in j.channels.iter().zip(values) {
            // Many joints carry all-zero channels (CMU's hip joints, fingers): skip the trig.
            if v == 0.0 && !matches!(channel, Channel::PosX | Channel::PosY | Channel::PosZ) {
                continue;
            }
            match channel {
                Channel::PosX => translation.x = v,
                Channel::PosY => translation.y = v,
                Channel::PosZ => translation.z = v,
                Channel::RotX => rotation *= DQuat::from_rotation_x(v.to_radians()),
                Channel::RotY => rotation *= DQuat::from_rotation_y(v.to_radians()),
                Channel::RotZ => rotation *= DQuat::from_rotation_z(v.to_radians()),
            }
        }
        (translation, rotation)
    }
}

/// The name of a UTF-16/32 encoding recognized by its byte-order mark or by the NUL bytes
/// interleaved with ASCII at the start, `None` for anything else.
fn wide_encoding(bytes: &[u8]) -> Option<&'static str> {
    match bytes {
        [0xFF, 0xFE, 0, 0, ..] | [0, 0, 0xFE, 0xFF, ..] => Some("UTF-32"),
        [0xFF, 0xFE, ..] => Some("UTF-16 (little-endian)"),
        [0xFE, 0xFF, ..] => Some("UTF-16 (big-endian)"),
        [a, 0, 0, 0, ..] if a.is_ascii_graphic() => Some("UTF-32 (little-endian)"),
        [a, 0, b, 0, ..] if a.is_ascii_graphic() && b.is_ascii() => Some("UTF-16 (little-endian)"),
        [0, a, 0, b, ..] if a.is_ascii_graphic() && b.is_ascii() => Some("UTF-16 (big-endian)"),
        _ => None,
    }
}

struct Parser<'a> {
    file: &'a str,
    text: &'a str,
    pos: usize,
    line: usize,
}

impl<'a> Parser<'a> {
    fn error(&self, message: impl Into<String>) -> Error {
        Error::bvh(self.file, self.line, message)
    }

    fn error_at(&self, line: usize, message: impl Into<String>) -> Error {
        Error::bvh(self.file, line, message)
    }

    /// Skips whitespace (counting lines) and returns the next token with its line, or `None`
    /// at end of input.
    fn token(&mut self) -> Option<(&'a str, usize)> {
        let bytes = self.text.as_bytes();
        while self.pos < bytes.len() && bytes[self.pos].is_ascii_whitespace() {
            if bytes[self.pos] == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        if self.pos >= bytes.len() {
            return None;
        }
        let start = self.pos;
        while self.pos < bytes.len() && !bytes[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        Some((&self.text[start..self.pos], self.line))
    }

    /// The error for input ending where `what` was expected.
    fn eof(&self, what: &str) -> Error {
        // Name the last line: editors jump to it, and "file:line" is what every error here gives.
        Error::bvh(self.file, self.line.max(1), format!("unexpected end of file: expected {what}"))
    }

    fn expect_token(&mut self, what: &str) -> Result<(&'a str, usize)> {
        self.token().ok_or_else(|| self.eof(what))
    }

    fn expect_keyword(&mut self, keyword: &str) -> Result<usize> {
        let (token, line) = self.token().ok_or_else(|| self.eof(&format!("'{keyword}'")))?;
        if token.eq_ignore_ascii_case(keyword) {
            Ok(line)
        } else {
            Err(self.error_at(line, format!("expected '{keyword}', found '{}'", quote(token))))
        }
    }

    /// The rest of the current line, trimmed (joint names may contain spaces).
    fn rest_of_line(&mut self) -> &'a str {
        let bytes = self.text.as_bytes();
        let start = self.pos;
        while self.pos < bytes.len() && bytes[self.pos] != b'\n' {
            self.pos += 1;
        }
        self.text[start..self.pos].trim()
    }

    /// A finite number within ±[`MAX_ABS_BVH_VALUE`].
    fn number(&mut self, what: &str) -> Result<f64> {
        let (token, line) = self.expect_token(what)?;
        let value = parse_finite(token)
            .ok_or_else(|| self.error_at(line, format!("expected {what}, found '{}'", quote(token))))?;
        if value.abs() > MAX_ABS_BVH_VALUE {
            return Err(
                self.error_at(line, format!("{what} is {value:e}, out of range (magnitude ≤ {MAX_ABS_BVH_VALUE:e})"))
            );
        }
        Ok(value)
    }

    fn parse(mut self) -> Result<Bvh> {
        self.expect_keyword("HIERARCHY")?;
        let (root, line) = self.expect_token("'ROOT'")?;
        if !root.eq_ignore_ascii_case("ROOT") {
            return Err(self.error_at(line, format!("expected 'ROOT', found '{}'", quote(root))));
        }
        let (joints, num_channels) = self.hierarchy(line)?;

        let (token, line) = self.expect_token("'MOTION'")?;
        if token.eq_ignore_ascii_case("ROOT") {
            return Err(self.error_at(line, "a second ROOT hierarchy is not supported (one skeleton per file)"));
        }
        if !token.eq_ignore_ascii_case("MOTION") {
            return Err(self.error_at(line, format!("expected 'MOTION' after the hierarchy, found '{}'", quote(token))));
        }
        let frames_line = self.expect_keyword("Frames:")?;
        let (token, _) = self.expect_token("the frame count after 'Frames:'")?;
        let frames = parse_finite(token).unwrap_or(f64::NAN);
        if !(frames >= 0.0 && frames.fract() == 0.0 && frames <= MAX_FRAMES as f64) {
            return Err(self.error_at(
                frames_line,
                format!("'Frames:' must be a whole number from 0 to {MAX_FRAMES}, found '{}'", quote(token)),
            ));
        }
        let num_frames = frames as usize;
        let time_line = self.expect_keyword("Frame")?;
        let (time, _) = self.expect_token("'Time:'")?;
        if !time.eq_ignore_ascii_case("Time:") {
            return Err(self.error_at(time_line, format!("expected 'Frame Time:', found 'Frame {}'", quote(time))));
        }
        let (token, _) = self.expect_token("the frame time in seconds after 'Frame Time:'")?;
        let frame_time = parse_finite(token).unwrap_or(f64::NAN);
        if !(MIN_FRAME_TIME..=MAX_FRAME_TIME).contains(&frame_time) {
            return Err(self.error_at(
                time_line,
                format!(
                    "'Frame Time:' must be {MIN_FRAME_TIME} to {MAX_FRAME_TIME} seconds (10000 to 1 fps), found '{}'",
                    quote(token)
                ),
            ));
        }
        let values = self.motion(num_frames, num_channels, frames_line)?;
        Ok(Bvh { joints, num_channels, num_frames, frame_time, values, role_hints: Vec::new() })
    }

    /// Parses the hierarchy whose `ROOT` keyword was just read at `root_line`: the joints and
    /// the total channel count. Iterative (an explicit stack of open joints), so nesting depth
    /// costs heap, not call stack, and is bounded by [`MAX_DEPTH`].
    fn hierarchy(&mut self, root_line: usize) -> Result<(Vec<BvhJoint>, usize)> {
        let mut joints = Vec::new();
        let mut num_channels = 0;
        // Open joints, innermost last: (index, whether its OFFSET was read).
        let mut open: Vec<(usize, bool)> = Vec::new();
        self.open_joint(None, root_line, &mut joints, num_channels)?;
        open.push((0, false));
        while let Some(&(index, seen_offset)) = open.last() {
            let Some((token, line)) = self.token() else {
                return Err(self.eof(&format!("'}}' closing joint '{}'", quote(&joints[index].name))));
            };
            if token.eq_ignore_ascii_case("OFFSET") {
                joints[index].offset = self.vec3("OFFSET")?;
                open.last_mut().unwrap().1 = true;
            } else if token.eq_ignore_ascii_case("CHANNELS") {
                if !joints[index].channels.is_empty() {
                    return Err(self
                        .error_at(line, format!("joint '{}' has a second CHANNELS line", quote(&joints[index].name))));
                }
                let count = self.number("the channel count after 'CHANNELS'")?;
                if !(0.0..=6.0).contains(&count) || count.fract() != 0.0 {
                    return Err(self.error_at(line, format!("CHANNELS count must be 0 to 6, found {count}")));
                }
                let mut channels = Vec::with_capacity(count as usize);
                for _ in 0..count as usize {
                    let (channel, cline) = self.expect_token("a channel name")?;
                    let channel = Channel::from_name(channel).ok_or_else(|| {
                        self.error_at(
                            cline,
                            format!("expected a channel name (Xposition … Zrotation), found '{}'", quote(channel)),
                        )
                    })?;
                    if channels.contains(&channel) {
                        return Err(self.error_at(
                            cline,
                            format!("channel {channel:?} listed twice for joint '{}'", quote(&joints[index].name)),
                        ));
                    }
                    channels.push(channel);
                }
                num_channels += channels.len();
                joints[index].channels = channels;
            } else if token.eq_ignore_ascii_case("JOINT") {
                if !seen_offset {
                    return Err(self.error_at(
                        line,
                        format!("joint '{}' needs an OFFSET before its children", quote(&joints[index].name)),
                    ));
                }
                if open.len() >= MAX_DEPTH {
                    return Err(self.error_at(line, format!("the hierarchy is nested deeper than {MAX_DEPTH} joints")));
                }
                if joints.len() >= MAX_JOINTS {
                    return Err(self.error_at(line, format!("more than {MAX_JOINTS} joints")));
                }
                self.open_joint(Some(index), line, &mut joints, num_channels)?;
                open.push((joints.len() - 1, false));
            } else if token.eq_ignore_ascii_case("END") {
                let (site, sline) = self.expect_token("'Site'")?;
                if !site.eq_ignore_ascii_case("Site") && !site.eq_ignore_ascii_case("Site{") {
                    return Err(self.error_at(sline, format!("expected 'End Site', found 'End {}'", quote(site))));
                }
                if !site.ends_with('{') {
                    self.expect_keyword("{")?;
                }
                self.expect_keyword("OFFSET")?;
                let offset = self.vec3("End Site OFFSET")?;
                self.expect_keyword("}")?;
                joints[index].end_site = Some(offset);
            } else if token == "}" {
                if !seen_offset {
                    return Err(self.error_at(line, format!("joint '{}' has no OFFSET", quote(&joints[index].name))));
                }
                open.pop();
            } else {
                return Err(self.error_at(
                    line,
                    format!(
                        "expected OFFSET, CHANNELS, JOINT, End Site or '}}' in joint '{}', found '{}'",
                        quote(&joints[index].name),
                        quote(token)
                    ),
                ));
            }
        }
        Ok((joints, num_channels))
    }

    /// Reads the name and opening brace of a `ROOT`/`JOINT` whose keyword was just read at
    /// `line`, and appends the joint.
    fn open_joint(
        &mut self,
        parent: Option<usize>,
        line: usize,
        joints: &mut Vec<BvhJoint>,
        first_channel: usize,
    ) -> Result<()> {
        let mut name = self.rest_of_line();
        let mut brace_on_line = false;
        if let Some(stripped) = name.strip_suffix('{') {
            name = stripped.trim_end();
            brace_on_line = true;
        }
        if name.is_empty() {
            return Err(self.error_at(line, "joint has no name"));
        }
        if name.len() > MAX_NAME_BYTES {
            return Err(
                self.error_at(line, format!("joint name '{}' is longer than {MAX_NAME_BYTES} bytes", quote(name)))
            );
        }
        if joints.iter().any(|j| j.name == name) {
            return Err(self.error_at(line, format!("duplicate joint name '{}'", quote(name))));
        }
        if !brace_on_line {
            self.expect_keyword("{")?;
        }
        joints.push(BvhJoint {
            name: name.to_string(),
            parent,
            offset: DVec3::ZERO,
            channels: Vec::new(),
            first_channel,
            end_site: None,
        });
        Ok(())
    }

    fn vec3(&mut self, what: &str) -> Result<DVec3> {
        let x = self.number(&format!("{what} x"))?;
        let y = self.number(&format!("{what} y"))?;
        let z = self.number(&format!("{what} z"))?;
        Ok(DVec3::new(x, y, z))
    }

    /// Reads `num_frames` lines of `num_channels` numbers. Counting per line (rather than as
    /// one stream) lets a short or long line be reported where it is. This is the hot loop of
    /// the importer, so it works on bytes.
    fn motion(&mut self, num_frames: usize, num_channels: usize, frames_line: usize) -> Result<Vec<f64>> {
        let bytes = self.text.as_bytes();
        let n = bytes.len();
        // Finish the 'Frame Time' line.
        self.rest_of_line();
        // Reserve what the header declares, but never more than the remaining bytes can hold
        // (a number and its separator take at least 2 bytes): `Frames:` may claim anything.
        let declared = num_frames.saturating_mul(num_channels);
        let capacity = declared.min((n - self.pos).div_ceil(2));
        // Fallible: in WASM a page may already hold most of wasm32's 4 GiB, and a failed
        // allocation there is a trap that takes every object of the page with it.
        let mut values = Vec::new();
        values.try_reserve_exact(capacity).map_err(|_| {
            self.error_at(
                frames_line,
                format!(
                    "out of memory: the motion's {capacity} values ({:.1} MB) could not be allocated",
                    (capacity * 8) as f64 / 1e6
                ),
            )
        })?;
        let mut pos = self.pos;
        let mut frame = 0;
        while pos < n {
            if bytes[pos] == b'\n' {
                pos += 1;
                self.line += 1;
            }
            let line_start = pos;
            let before = values.len();
            loop {
                while pos < n && matches!(bytes[pos], b' ' | b'\t' | b'\r' | b'\x0c' | b'\x0b') {
                    pos += 1;
                }
                if pos >= n || bytes[pos] == b'\n' {
                    break;
                }
                if frame == num_frames {
                    return Err(self.error(format!(
                        "more frame lines than the {num_frames} declared by 'Frames:' on line {frames_line}"
                    )));
                }
                let (value, end) = match parse_decimal(bytes, pos) {
                    Some(parsed) => parsed,
                    None => {
                        let end = pos + bytes[pos..].iter().position(|b| b.is_ascii_whitespace()).unwrap_or(n - pos);
                        let token = &self.text[pos..end];
                        let v = parse_finite(token).ok_or_else(|| {
                            self.error(format!(
                                "frame {frame}: expected a number, found '{}' (column {})",
                                quote(token),
                                pos - line_start + 1
                            ))
                        })?;
                        (v, end)
                    }
                };
                // Both paths return finite values; one compare keeps 1e300 (or 1e39, ∞ in f32) out.
                if value.abs() > MAX_ABS_BVH_VALUE {
                    return Err(self.error(format!(
                        "frame {frame}: value {value:e} at column {} is out of range (magnitude ≤ {MAX_ABS_BVH_VALUE:e})",
                        pos - line_start + 1
                    )));
                }
                values.push(value);
                pos = end;
            }
            let found = values.len() - before;
            if found != 0 && found != num_channels {
                return Err(self.error(format!(
                    "frame {frame} has {found} values, expected {num_channels} (the total of the CHANNELS lines)"
                )));
            }
            if found != 0 {
                frame += 1;
            }
        }
        self.pos = pos;
        if frame < num_frames {
            return Err(Error::bvh(
                self.file,
                0,
                format!(
                    "'Frames:' on line {frames_line} declares {num_frames} frames but only {frame} frame lines follow"
                ),
            ));
        }
        Ok(values)
    }
}

/// Fast path for the plain decimals mocap files are made of (`-12.345678`): when the digits
/// fit in 2⁵³ and there are at most 22 after the point, `mantissa / 10^k` is one correctly
/// rounded IEEE division of two exact values — the same f64 `str::parse` returns (Clinger
/// 1990). Anything else (exponents, long mantissas, junk) returns `None` for the slow path.
fn parse_decimal(bytes: &[u8], start: usize) -> Option<(f64, usize)> {
    const POW10: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19,
        1e20, 1e21, 1e22,
    ];
    let mut i = start;
    let negative = match bytes[i] {
        b'-' => {
            i += 1;
            true
        }
        b'+' => {
            i += 1;
            false
        }
        _ => false,
    };
    let (mut mantissa, mut digits, mut fraction) = (0u64, 0u32, 0usize);
    let mut seen_point = false;
    while i < bytes.len() {
        match bytes[i] {
            d @ b'0'..=b'9' => {
                if digits == 19 {
                    return None;
                }
                mantissa = mantissa * 10 + (d - b'0') as u64;
                digits += 1;
                fraction += seen_point as usize;
            }
            b'.' if !seen_point => seen_point = true,
            b if b.is_ascii_whitespace() => break,
            _ => return None,
        }
        i += 1;
    }
    if digits == 0 || mantissa >= 1 << 53 || fraction > 22 {
        return None;
    }
    let v = mantissa as f64 / POW10[fraction];
    Some((if negative { -v } else { v }, i))
}

/// Parses a finite decimal number (`nan`/`inf` are rejected: they would poison every pose).
fn parse_finite(token: &str) -> Option<f64> {
    token.parse::<f64>().ok().filter(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) const TWO_JOINTS: &str = "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n  JOINT Chest\n  {\n    OFFSET 0 0.5 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n    End Site\n    {\n      OFFSET 0 0.3 0\n    }\n  }\n}\nMOTION\nFrames: 2\nFrame Time: 0.0333333\n0 1 0 0 0 0 0 0 0\n1 1 0 90 0 0 0 0 45\n";

    fn err(text: &str) -> String {
        match Bvh::parse("bad.bvh", text.as_bytes()) {
            Ok(_) => panic!("expected an error for:\n{text}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn parses_hierarchy_and_motion() {
        let bvh = Bvh::parse("t.bvh", TWO_JOINTS.as_bytes()).unwrap();
        assert_eq!(bvh.joints.len(), 2);
        assert_eq!(bvh.joints[1].parent, Some(0));
        assert_eq!(bvh.joints[1].end_site, Some(DVec3::new(0.0, 0.3, 0.0)));
        assert_eq!(bvh.num_channels, 9);
        assert_eq!(bvh.num_frames, 2);
        assert!((bvh.fps() - 30.0).abs() < 1e-3);
        let (t, r) = bvh.local_transform(1, 0);
        assert_eq!(t, DVec3::new(1.0, 1.0, 0.0));
        assert!(r.angle_between(DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2)) < 1e-12);
    }

    #[test]
    fn crlf_tabs_and_spaces_in_names() {
        let text = TWO_JOINTS.replace("\n", "\r\n").replace("  ", "\t").replace("JOINT Chest", "JOINT Upper Chest");
        let bvh = Bvh::parse("t.bvh", text.as_bytes()).unwrap();
        assert_eq!(bvh.joints[1].name, "Upper Chest");
        assert_eq!(bvh.num_frames, 2);
    }

    #[test]
    fn position_channels_replace_offset_components() {
        let text = TWO_JOINTS.replace(
            "OFFSET 0 0.5 0\n    CHANNELS 3 Zrotation Xrotation Yrotation",
            "OFFSET 7 0.5 9\n    CHANNELS 4 Yposition Zrotation Xrotation Yrotation",
        );
        let text = text.replace("0 1 0 0 0 0 0 0 0\n1 1 0 90 0 0 0 0 45", "0 1 0 0 0 0 2 0 0 0\n1 1 0 90 0 0 3 0 0 45");
        let bvh = Bvh::parse("t.bvh", text.as_bytes()).unwrap();
        assert_eq!(bvh.local_transform(1, 1).0, DVec3::new(7.0, 3.0, 9.0));
    }

    /// Every Euler order composes as R = R(first) · R(second) · R(third), checked against
    /// rotation matrices built independently by Rodrigues' formula.
    #[test]
    fn all_six_rotation_orders() {
        use glam::DMat3;
        let rodrigues = |axis: DVec3, deg: f64| {
            let (s, c) = deg.to_radians().sin_cos();
            let k = DMat3::from_cols(
                DVec3::new(0.0, axis.z, -axis.y),
                DVec3::new(-axis.z, 0.0, axis.x),
                DVec3::new(axis.y, -axis.x, 0.0),
            );
            DMat3::IDENTITY + k * s + k * k * (1.0 - c)
        };
        let angles = [23.0, -71.0, 118.0];
        for order in ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"] {
            let channels: Vec<String> = order.chars().map(|c| format!("{c}rotation")).collect();
            let text = format!(
                "HIERARCHY\nROOT a\n{{\nOFFSET 0 0 0\nCHANNELS 3 {}\n}}\nMOTION\nFrames: 1\nFrame Time: 0.01\n{} {} {}\n",
                channels.join(" "),
                angles[0],
                angles[1],
                angles[2]
            );
            let bvh = Bvh::parse("t.bvh", text.as_bytes()).unwrap();
            let expected = order.chars().zip(angles).fold(DMat3::IDENTITY, |m, (c, a)| {
                let axis = match c {
                    'X' => DVec3::X,
                    'Y' => DVec3::Y,
                    _ => DVec3::Z,
                };
                m * rodrigues(axis, a)
            });
            let got = DMat3::from_quat(bvh.local_transform(0, 0).1);
            assert!((got - expected).to_cols_array().iter().all(|d| d.abs() < 1e-12), "order {order}");
        }
    }

    /// The decimal fast path returns exactly what `str::parse` returns, or defers to it.
    #[test]
    fn decimal_fast_path_is_bit_identical_to_std() {
        let mut seed = 0x9E3779B97F4A7C15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let mut fast = 0;
        for i in 0..200_000 {
            let int = next() % [10, 1000, 100_000, 10_000_000_000][i % 4];
            let frac = next() % 10u64.pow((i % 9) as u32 + 1);
            let sign = if next() % 2 == 0 { "-" } else { "" };
            let text = format!("{sign}{int}.{frac:0width$} ", width = (i % 9) + 1);
            let expected: f64 = text.trim().parse().unwrap();
            if let Some((v, end)) = parse_decimal(text.as_bytes(), 0) {
                assert_eq!(v.to_bits(), expected.to_bits(), "{text}");
                assert_eq!(end, text.len() - 1);
                fast += 1;
            }
        }
        assert!(fast > 150_000, "the fast path should take most plain decimals ({fast})");
        for odd in
            ["1e5", "1.5E-3", "12345678901234567890.5", "0.12345678901234567890123", "--1", "1.2.3", "nan", "inf", "."]
        {
            assert!(parse_decimal(odd.as_bytes(), 0).is_none(), "{odd} must take the slow path");
        }
        assert_eq!(parse_decimal(b"-0.000000\n", 0), Some((-0.0, 9)));
    }

    /// Malformed inputs: each must fail with the right line number and say what was expected.
    #[test]
    fn malformed_inputs_name_the_line() {
        let cases: &[(&str, &str, &str)] = &[
            ("empty", "", "end of file: expected 'HIERARCHY'"),
            ("no hierarchy", "ROOT x\n", ":1: expected 'HIERARCHY'"),
            ("no root", "HIERARCHY\nJOINT x\n", ":2: expected 'ROOT'"),
            ("missing brace", "HIERARCHY\nROOT x\nOFFSET 0 0 0\n", ":3: expected '{'"),
            ("bad offset", "HIERARCHY\nROOT x\n{\nOFFSET 0 zero 0\n", ":4: expected OFFSET y, found 'zero'"),
            ("unknown channel", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 1 Wrotation\n", ":5: expected a channel name"),
            ("too many channels", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 7 Xrotation\n", ":5: CHANNELS count must be 0 to 6"),
            ("duplicate channel", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 2 Xrotation\nXrotation\n", ":6: channel RotX listed twice"),
            ("unknown keyword", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nROTATION 1 2 3\n", ":5: expected OFFSET, CHANNELS, JOINT, End Site or '}'"),
            ("no offset", "HIERARCHY\nROOT x\n{\nCHANNELS 0\n}\n", ":5: joint 'x' has no OFFSET"),
            ("unnamed joint", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nJOINT\n{\n", ":5: joint has no name"),
            ("duplicate joint", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nJOINT x\n", ":5: duplicate joint name 'x'"),
            ("bad end site", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nEnd Effector\n", ":5: expected 'End Site'"),
            ("unclosed", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\n", "end of file: expected '}' closing joint 'x'"),
            ("no motion", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\n}\nFRAMES\n", ":6: expected 'MOTION'"),
            ("two roots", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\n}\nROOT y\n", ":6: a second ROOT"),
            ("bad frames", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\n}\nMOTION\nFrames: 2.5\n", ":7: 'Frames:' must be a whole number from 0 to 16777216, found '2.5'"),
            ("no frame time", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\n}\nMOTION\nFrames: 1\nTime: 1\n", ":8: expected 'Frame'"),
            ("zero frame time", "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\n}\nMOTION\nFrames: 1\nFrame Time: 0\n", ":8: 'Frame Time:' must be 0.0001 to 1 seconds"),
            (
                "short frame",
                "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n}\nMOTION\nFrames: 2\nFrame Time: 0.01\n1 2 3\n1 2\n",
                ":11: frame 1 has 2 values, expected 3",
            ),
            (
                "not a number",
                "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0.01\n1 2.0.1 3\n",
                ":10: frame 0: expected a number, found '2.0.1' (column 3)",
            ),
            (
                "nan value",
                "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0.01\nnan\n",
                ":10: frame 0: expected a number, found 'nan'",
            ),
            (
                "missing frames",
                "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\nMOTION\nFrames: 3\nFrame Time: 0.01\n1\n2\n",
                "end of file: 'Frames:' on line 8 declares 3 frames but only 2",
            ),
            (
                "extra frames",
                "HIERARCHY\nROOT x\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0.01\n1\n2\n",
                ":11: more frame lines than the 1 declared",
            ),
        ];
        assert!(cases.len() >= 15);
        for (what, text, expected) in cases {
            let message = err(text);
            assert!(message.contains(expected), "{what}: got '{message}', expected it to contain '{expected}'");
            assert!(message.starts_with("bad.bvh"), "{what}: message must name the file: {message}");
        }
    }

    /// What real exporters also write: a UTF-8 byte-order mark, CR-only line ends.
    #[test]
    fn bom_and_cr_only_line_ends_are_read() {
        let with_bom = [b"\xEF\xBB\xBF".as_slice(), TWO_JOINTS.as_bytes()].concat();
        assert_eq!(Bvh::parse("t.bvh", &with_bom).unwrap().num_frames, 2);
        let cr = TWO_JOINTS.replace('\n', "\r");
        assert_eq!(Bvh::parse("t.bvh", cr.as_bytes()).unwrap().num_frames, 2);
        // Lines are still counted on a CR-only file.
        let bad = cr.replace("Frame Time: 0.0333333", "Frame Time: 0");
        assert!(err(&bad).contains("bad.bvh:18: 'Frame Time:'"), "{}", err(&bad));
    }

    /// The limits of `crate::limits`, each a short error naming the line.
    #[test]
    fn limits_give_short_errors() {
        let utf16: Vec<u8> = TWO_JOINTS.encode_utf16().flat_map(|u| u.to_le_bytes()).collect();
        let e = Bvh::parse("w.bvh", &utf16).unwrap_err().to_string();
        assert!(e.contains("w.bvh:1: the file is UTF-16 (little-endian) text"), "{e}");
        let deep: String = (0..300).map(|i| format!("JOINT j{i}\n{{\nOFFSET 0 0 0\n")).collect();
        let e = err(&format!("HIERARCHY\nROOT r\n{{\nOFFSET 0 0 0\n{deep}"));
        assert!(e.contains(":770: the hierarchy is nested deeper than 256"), "{e}");
        let huge = TWO_JOINTS.replace("Frames: 2", "Frames: 2147483648");
        assert!(err(&huge).contains(":17: 'Frames:' must be a whole number from 0 to 16777216"));
        for t in ["1e300", "1e-300", "nan", "-0.01", "2"] {
            let e = err(&TWO_JOINTS.replace("0.0333333", t));
            assert!(e.contains(":18: 'Frame Time:' must be 0.0001 to 1 seconds"), "{t}: {e}");
        }
        for v in ["1e308", "1e39", "-2e7"] {
            let e = err(&TWO_JOINTS.replace("1 1 0 90", &format!("1 1 0 {v}")));
            assert!(e.contains(":20: frame 1: value") && e.contains("out of range"), "{v}: {e}");
        }
        let e = err(&TWO_JOINTS.replace("OFFSET 0 0.5 0", "OFFSET 0 1e300 0"));
        assert!(e.contains(":8: OFFSET y is 1e300, out of range"), "{e}");
        let e = err(&TWO_JOINTS.replace("1 1 0 90", &format!("1 1 0 {}", "x".repeat(1 << 20))));
        assert!(e.len() < 200 && e.contains("xxx…'"), "{e}");
    }
}
