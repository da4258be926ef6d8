//! Every limit the importers put on untrusted input, in one place (also listed, with the
//! reasoning, in `docs/robustness.md`).
//!
//! BVH text and `.mmdb` bytes come from users (dropped on the page, passed to the CLI). A
//! header may claim any count, so buffers are sized from the bytes actually present, never
//! from a declared count; nesting is bounded; and every number that later drives a loop, a
//! division or an allocation is range-checked where it is read, so the error can name the file
//! and line (or section and field) instead of surfacing later as NaN, a hang or an abort.
//!
//! | what | limit | why |
//! |---|---|---|
//! | BVH joints | ≤ [`MAX_JOINTS`] (1,024) | real skeletons have 20–150 (CMU 31, Daz 43, with fingers ~70); keeps name checks and per-joint work bounded |
//! | BVH hierarchy depth | ≤ [`MAX_DEPTH`] (256) | a human chain is < 30 deep; the parser is iterative, the limit keeps per-chain work (and any recursive consumer) bounded |
//! | joint name | ≤ [`MAX_NAME_BYTES`] (256 bytes) | names end up in every database and message |
//! | `Frames:` | whole, 0 ≤ n ≤ [`MAX_FRAMES`] (2²⁴) | frame indices stay exact in f32 and u32 on every target; buffers are still sized from the bytes present |
//! | `Frame Time:` | [`MIN_FRAME_TIME`] … [`MAX_FRAME_TIME`] s (10,000 to 1 fps) | anything else is a typo or corruption, and it sets the resampling ratio |
//! | BVH numbers | finite, abs ≤ [`MAX_ABS_BVH_VALUE`] (10⁷) | 10 km in mm, 27,000 turns in degrees; larger values overflow f32 or square to ∞ downstream |
//! | database fps (`--fps`, config, `INFO.fps`) | [`MIN_FPS`] … [`MAX_FPS`] (1 to 1,000) | the runtime advances `fps · dt` frames per update; a huge fps spins it |
//! | unit scale (`--scale`, config, `CLIP.scale`) | [`MIN_SCALE`] … [`MAX_SCALE`] (10⁻⁶ to 10³ m per unit) | µm to km per unit covers every real unit; outside it positions underflow or overflow f32 |
//! | configuration windows, `contact_speed` | ≤ [`MAX_WINDOW_SECONDS`] (60 s), ≤ [`MAX_SPEED`] (100 m/s) | a window of 10³⁰⁰ s would be a 2⁶⁴-frame filter |
//! | feature weight (config), offsets | [`MIN_WEIGHT`] … [`MAX_WEIGHT`], abs ≤ [`MAX_FEATURE_OFFSET`] frames | the feature scale is std / weight |
//! | `.mmdb` floats | finite, abs ≤ [`MAX_ABS_STORED`] (10¹²) | squared distances of such values stay finite in f32 |
//! | `.mmdb` quaternions | unit length ± [`QUAT_NORM_TOLERANCE`] | the writer stores unit quaternions; others scale the skeleton |
//! | `.mmdb` feature scale | [`MIN_FEATURE_SCALE`] … [`MAX_FEATURE_SCALE`] | a query is divided by it at run time |
//! | `.mmdb` feature offsets | abs ≤ [`MAX_FEATURE_OFFSET`] frames | 10 s at 1,000 fps; the runtime predicts that far |
//! | `.mmdb` allocation | ≤ [`MMDB_ALLOCATION_FACTOR`] × file size | every count is checked against the bytes that must hold it, and (version 3) what the derived features and mirrored clips will cost against the file's size |
//! | BVH allocation | ≤ [`BVH_ALLOCATION_FACTOR`] × file size + 1 MiB | values are at least 2 bytes of text each; non-UTF-8 text may triple when made readable |
//! | a built database | ≤ [`MAX_DATABASE_BYTES`] (1 GiB), ≤ [`MAX_FRAMES`] frames ([`check_database_size`]) | resampling a 1 fps take to 1,000 fps grows it 1,000-fold; wasm32 has 4 GiB |
//! | feature dimensions (config, build, `INFO`, search) | 1 … [`MAX_FEATURE_DIMS`] (128) ([`check_feature_dims`]) | the search keeps a query's lanes on the stack, so a search never allocates |
//! | memory a build needs (estimated before it allocates) | ≤ [`MAX_BUILD_BYTES`] (3 GiB) ([`BuildFootprint`]) | wasm32 holds 4 GiB in all; an allocation that fails there is a trap |
//! | a take's reach (values × scale, chained) | ≤ [`MAX_REACH`] (10⁵ m) | so positions, velocities at 1,000 fps and feature scales stay within what the loader accepts |
//! | root-motion scale of a take | [`1 / MAX_ROOT_SCALE`](MAX_ROOT_SCALE) … [`MAX_ROOT_SCALE`] (10³) | the builder keeps a take's root motion unscaled outside it (`CLIP.root_scale`) |
//! | configuration windows at the database fps | ≤ [`MAX_WINDOW_FRAMES`] (1,000) frames | the smoothing weights are window² floats, the contact vote window × frames steps |
//! | characters in one crowd | ≤ `crowd::Crowd::max_characters`: [`CROWD_SEARCH_BUDGET`] / (frames × dims), [`CROWD_MEMORY_BUDGET`] / bytes per character, 1 … [`MAX_CROWD`] | every character searches at its first update: 100,000 took 304 s |
//! | quoted input in a message | [`MAX_QUOTE_CHARS`] characters | a 1 MB token must not become a 1 MB message |
//! | a whole message | [`MAX_MESSAGE_CHARS`] characters | same, as a backstop for every error of the crate |

/// Joints in one BVH hierarchy (`ROOT`, `JOINT`; `End Site`s do not count).
pub const MAX_JOINTS: usize = 1024;
/// Nesting depth of the BVH hierarchy (the root is depth 1).
pub const MAX_DEPTH: usize = 256;
/// Length of a joint name in bytes.
pub const MAX_NAME_BYTES: usize = 256;
/// `Frames:` of one BVH file.
pub const MAX_FRAMES: usize = 1 << 24;
/// Shortest `Frame Time:` (seconds): 10,000 fps.
pub const MIN_FRAME_TIME: f64 = 1e-4;
/// Longest `Frame Time:` (seconds): 1 fps.
pub const MAX_FRAME_TIME: f64 = 1.0;
/// Magnitude of any number in a BVH file (OFFSET, channel values).
pub const MAX_ABS_BVH_VALUE: f64 = 1e7;
/// Database frame rate, frames per second.
pub const MIN_FPS: f64 = 1.0;
pub const MAX_FPS: f64 = 1000.0;
/// Source frame rate stored in a clip (`1 / Frame Time`).
pub const MIN_SOURCE_FPS: f64 = 1.0 / MAX_FRAME_TIME;
pub const MAX_SOURCE_FPS: f64 = 1.0 / MIN_FRAME_TIME;
/// Unit scale, metres per source unit.
pub const MIN_SCALE: f64 = 1e-6;
pub const MAX_SCALE: f64 = 1e3;
/// Longest filter or smoothing window of the configuration, seconds.
pub const MAX_WINDOW_SECONDS: f64 = 60.0;
/// Largest speed threshold of the configuration (`contact_speed`), m/s.
pub const MAX_SPEED: f64 = 100.0;
/// Magnitude of any float stored in a `.mmdb` file.
pub const MAX_ABS_STORED: f32 = 1e12;
/// `| |q|² − 1 |` allowed for a stored rotation.
pub const QUAT_NORM_TOLERANCE: f32 = 1e-3;
/// Per-dimension feature normalization scale (`FNRM`); the builder's smallest is
/// `1e-8 / MAX_WEIGHT`.
pub const MIN_FEATURE_SCALE: f32 = 1e-12;
pub const MAX_FEATURE_SCALE: f32 = 1e12;
/// Feature group weight (configuration).
pub const MIN_WEIGHT: f32 = 1e-3;
pub const MAX_WEIGHT: f32 = 1e3;
/// Frame offset of a feature group, in frames (past or future).
pub const MAX_FEATURE_OFFSET: i32 = 10_000;
/// Peak heap use of [`crate::format::from_bytes`], as a multiple of the file size (plus 64 KiB).
pub const MMDB_ALLOCATION_FACTOR: usize = 24;
/// Peak heap use of [`crate::bvh::Bvh::parse`], as a multiple of the input size (plus 1 MiB).
pub const BVH_ALLOCATION_FACTOR: usize = 8;
/// Characters of user input quoted in a message.
pub const MAX_QUOTE_CHARS: usize = 40;
/// Characters of a whole error message (longer ones are cut with `…`).
pub const MAX_MESSAGE_CHARS: usize = 300;

/// `text` for an error message: at most [`MAX_QUOTE_CHARS`] characters (then `…`), control and
/// invisible characters escaped (`\u{feff}`, `\0`) so that what differs is visible.
pub fn quote(text: &str) -> String {
    let mut out = String::with_capacity(text.len().min(4 * MAX_QUOTE_CHARS) + 3);
    for (i, c) in text.chars().enumerate() {
        if i == MAX_QUOTE_CHARS {
            out.push('…');
            break;
        }
        if c.is_control() || matches!(c, '\u{feff}' | '\u{200b}'..='\u{200f}' | '\u{2028}' | '\u{2029}') {
            out.extend(c.escape_debug());
        } else {
            out.push(c);
        }
    }
    out
}

/// A number for a message: plain when it reads well (`60`, `0.0254`), in scientific notation
/// otherwise (`1e300` rather than a 301-digit integer, `1e-40` rather than 40 zeros).
/// An f32 prints as the shortest f32 (`1e30`, not `1.0000000150474662e30`).
pub fn num<T: Copy + Into<f64> + std::fmt::Display + std::fmt::LowerExp>(v: T) -> String {
    let x: f64 = v.into();
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&x.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `message` cut to [`MAX_MESSAGE_CHARS`] characters (on a character boundary, then `…`).
pub fn cap_message(mut message: String) -> String {
    if message.len() > MAX_MESSAGE_CHARS {
        if let Some((cut, _)) = message.char_indices().nth(MAX_MESSAGE_CHARS) {
            message.truncate(cut);
            message.push('…');
        }
    }
    message
}

/// Checks a database frame rate.
///
/// # Errors
/// A message naming the allowed range when `fps` is not in [`MIN_FPS`]…[`MAX_FPS`] (NaN and
/// infinities included).
pub fn check_fps(fps: f64) -> std::result::Result<(), String> {
    if (MIN_FPS..=MAX_FPS).contains(&fps) {
        Ok(())
    } else {
        Err(format!("fps must be between {MIN_FPS} and {MAX_FPS}, found {}", num(fps)))
    }
}

/// Checks a unit scale (metres per source unit).
///
/// # Errors
/// A message naming the allowed range when `scale` is not in [`MIN_SCALE`]…[`MAX_SCALE`].
pub fn check_scale(scale: f64) -> std::result::Result<(), String> {
    if (MIN_SCALE..=MAX_SCALE).contains(&scale) {
        Ok(())
    } else {
        Err(format!(
            "scale must be between {} and {} metres per unit, found {}",
            num(MIN_SCALE),
            num(MAX_SCALE),
            num(scale)
        ))
    }
}

/// Feature dimensions of a database. The search ([`crate::search::SearchIndex`]) splats a
/// query and its weights across lanes on the stack (2 × 2 KiB at 128) so that a search never
/// allocates; the default feature set has 27 dims. Checked by the configuration, the builder,
/// the loader (`INFO.num_feature_dims`) and the search itself.
pub const MAX_FEATURE_DIMS: usize = 128;

/// Checks a feature dimension count: 1 to [`MAX_FEATURE_DIMS`].
///
/// # Errors
/// A message with the count and the limit.
pub fn check_feature_dims(dims: usize) -> std::result::Result<(), String> {
    if (1..=MAX_FEATURE_DIMS).contains(&dims) {
        Ok(())
    } else {
        Err(format!(
            "{dims} feature dimensions; the search takes 1 to {MAX_FEATURE_DIMS} (fewer groups, offsets or axes)"
        ))
    }
}

/// Farthest a take's joints may reach from the origin, in metres: every BVH value (offsets and
/// position channels, at most [`MAX_ABS_BVH_VALUE`]) times the unit scale (up to
/// [`MAX_SCALE`]) and the root-motion scale, summed along each joint chain. Within it, a
/// position is ≤ 10⁵ m, a velocity at 1,000 fps ≤ 2·10⁸ m/s and so every feature scale
/// (std / weight ≤ 2·10¹¹) and stored float stays inside what the loader accepts; 100 km is
/// also how far the runtime lets a character be teleported or walk a path.
pub const MAX_REACH: f64 = 1e5;

/// Root-motion scale of a clip (`CLIP.root_scale`): a take whose legs are more than 1,000
/// times longer or shorter than the reference's keeps its root motion unscaled.
pub const MAX_ROOT_SCALE: f32 = 1e3;

/// Longest configuration window in database frames (`contact_filter`, `root_position_window`,
/// `root_facing_window` times the fps): a Savitzky–Golay window of w frames keeps w² f64
/// weights for the session (8 MB at 1,001 frames; a 60 s window at 1,000 fps on a minute-long take would need 29 GB),
/// and the contact vote takes 2w steps per frame.
pub const MAX_WINDOW_FRAMES: f64 = 1000.0;

/// Largest database a build may produce, in bytes of its arrays (pose arrays, contacts,
/// features, validity): wasm32 has 4 GiB of address space, shared with the sources and the
/// builder's f64 intermediates (about twice the output).
pub const MAX_DATABASE_BYTES: u64 = 1 << 30;

/// Checks, before anything is allocated, that a database of `frames` frames, `joints` joints
/// (the virtual root included) and `dims` feature dimensions stays within
/// [`MAX_DATABASE_BYTES`] (and [`MAX_FRAMES`] frames). A builder should call this with the
/// sum of [`resampled_frames`] over its takes: a 2 MB BVH at 1 fps resampled to 1,000 fps
/// would otherwise ask for 156 GB.
///
/// # Errors
/// A message with the frame count and size when the database would be too large.
pub fn check_database_size(frames: usize, joints: usize, dims: usize) -> std::result::Result<(), String> {
    // LPOS, LVEL, LAVL (12 B each), LROT (16 B) per joint; FEAT 4 B per dim; CONT 2 B, VALD 1 B.
    let per_frame = joints as u64 * 52 + dims as u64 * 4 + 3;
    let bytes = (frames as u64).saturating_mul(per_frame);
    if frames > MAX_FRAMES || bytes > MAX_DATABASE_BYTES {
        return Err(format!(
            "the database would have {frames} frames ({:.1} GB); the limit is {MAX_FRAMES} frames and {:.1} GB — use fewer or shorter takes, or a lower fps",
            bytes as f64 / 1e9,
            MAX_DATABASE_BYTES as f64 / 1e9
        ));
    }
    Ok(())
}

/// Most memory a build may need, in bytes (see [`BuildFootprint`]): wasm32 holds 4 GiB in all,
/// and the page keeps the module's code, its databases and characters in the rest. The same
/// limit holds natively, so a database the CLI builds can be built in the page too.
pub const MAX_BUILD_BYTES: u64 = 3 << 30;

/// What a build will hold at its peak, counted before it allocates anything: the parsed
/// sources, the database's arrays, the f64 working copies of the largest take and the `.mmdb`
/// bytes written. [`BuildFootprint::bytes`] is an upper bound
/// of the heap a single-threaded build (WASM) holds, measured against a counting allocator by
/// `tests/build_limits.rs`; a native build runs takes on several threads, each with its own
/// working copies.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BuildFootprint {
    /// Heap bytes the parsed sources hold (8 per BVH value, plus names).
    pub source_bytes: u64,
    /// Database frames, joints (the virtual root included) and feature dimensions.
    pub frames: u64,
    pub joints: u64,
    pub dims: u64,
    /// Output frames of the longest take, and the most joints a take's working copies have
    /// (its own skeleton's plus the reference's when it is retargeted).
    pub take_frames: u64,
    pub take_joints: u64,
    /// Working copies of a take besides the resampled one: 1 per mirrored or reversed variant.
    pub take_copies: u64,
    /// Bytes of names in the database (clips, tags, joints), written into the file.
    pub name_bytes: u64,
}

impl BuildFootprint {
    /// The estimated peak, in bytes (saturating).
    pub fn bytes(&self) -> u64 {
        let m = |a: u64, b: u64| a.saturating_mul(b);
        let (n, j, d) = (self.frames, self.joints, self.dims);
        // The database's arrays while the takes are built (positions 12 B and rotations 16 B
        // per joint, 4 B per feature, 2 contact bytes), and once whole (+ 1 validity byte).
        let rows = m(n, m(j, 28) + m(d, 4) + 2);
        let whole = m(n, m(j, 28) + m(d, 4) + 3);
        // One take's f64 working copies: the resampled local transforms (56 B per joint), one
        // per mirrored/reversed variant, world transforms, the rows with the virtual root, the
        // root itself and its smoothing inputs, contacts.
        let t = self.take_frames;
        let take = m(t, m(self.take_joints, 56).saturating_mul(2 + self.take_copies) + m(j, 56) + 56 + 48 + 2);
        // The file: encoded poses (≤ 12 B per animated joint position, 8 B per rotation),
        // shuffled features and the flags, held twice while the file is assembled.
        let file = m(n, m(j, 20) + m(d, 4) + 3).saturating_add(self.name_bytes).saturating_add(1 << 16);
        let peak = (rows.saturating_add(take)).max(whole.saturating_add(m(file, 2)));
        // Small things (groups, tags, clip lists, the smoothing weights of two 1,001-frame
        // windows) and allocator rounding.
        self.source_bytes.saturating_add(peak).saturating_add(peak / 64).saturating_add(48 << 20)
    }

    /// Checks the estimate against [`MAX_BUILD_BYTES`].
    ///
    /// # Errors
    /// A message with the estimate, the limit and what to change.
    pub fn check(&self) -> std::result::Result<(), String> {
        let bytes = self.bytes();
        if bytes > MAX_BUILD_BYTES {
            return Err(format!(
                "the build would need about {:.1} GB of memory ({} frames, the longest take {} frames), more than the {:.1} GB a build may use (wasm32 holds 4 GB) — use fewer or shorter takes, or a lower fps",
                bytes as f64 / 1e9,
                self.frames,
                self.take_frames,
                MAX_BUILD_BYTES as f64 / 1e9
            ));
        }
        Ok(())
    }
}

/// Characters one crowd may hold, whatever the database: far past what a frame can update (a
/// few hundred in 4 ms), low enough that a typo cannot ask wasm32 for gigabytes.
pub const MAX_CROWD: usize = 100_000;

/// Feature values a crowd update may compare when every character searches at once (its first
/// update, or a sharp input change for all): `count × frames × dims` ≤ this. 2³² is about a
/// second of WASM: 6,443 characters on the 24,688-frame, 27-dim locomotion database, whose
/// first update took 1.0 s in Node (docs/robustness.md); a crowd of 100,000 there took 304 s.
pub const CROWD_SEARCH_BUDGET: u64 = 1 << 32;

/// Memory a crowd's characters may hold (`crowd::character_bytes` each).
pub const CROWD_MEMORY_BUDGET: u64 = 256 << 20;

/// Frames a take of `source_frames` frames at `source_fps` gives when resampled to `fps`,
/// the way the builder counts them, or `None` when that exceeds [`MAX_FRAMES`] (a builder
/// can call this before allocating: a 1 fps source resampled to 1,000 fps grows 1,000-fold).
pub fn resampled_frames(source_frames: usize, source_fps: f64, fps: f64) -> Option<usize> {
    if source_frames == 0 {
        return Some(0);
    }
    let n = ((source_frames - 1) as f64 * fps / source_fps + 1e-9).floor() + 1.0;
    (n.is_finite() && n >= 0.0 && n <= MAX_FRAMES as f64).then_some(n as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quote_caps_and_escapes() {
        assert_eq!(quote("HIERARCHY"), "HIERARCHY");
        assert_eq!(quote("\u{feff}HIERARCHY"), "\\u{feff}HIERARCHY");
        assert_eq!(quote("a\0b"), "a\\0b");
        let long = "x".repeat(1_000_000);
        assert_eq!(quote(&long).chars().count(), MAX_QUOTE_CHARS + 1);
        assert_eq!(quote("é".repeat(50).as_str()).chars().count(), MAX_QUOTE_CHARS + 1);
    }

    #[test]
    fn messages_are_capped_on_char_boundaries() {
        let m = cap_message("é".repeat(1000));
        assert_eq!(m.chars().count(), MAX_MESSAGE_CHARS + 1);
        assert!(m.ends_with('…'));
        assert_eq!(cap_message("short".into()), "short");
    }

    #[test]
    fn numbers_stay_short() {
        assert_eq!(num(60.0), "60");
        assert_eq!(num(0.0254), "0.0254");
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(1e30_f32), "1e30");
        assert_eq!(num(1e-40), "1e-40");
        assert_eq!(num(f64::NAN), "NaN");
        assert!(check_fps(1e300).unwrap_err().len() < 80);
    }

    #[test]
    fn ranges() {
        assert!(check_fps(60.0).is_ok() && check_fps(1000.0).is_ok() && check_fps(1.0).is_ok());
        for bad in [0.0, -1.0, 1000.5, f64::NAN, f64::INFINITY, 1e300] {
            assert!(check_fps(bad).is_err(), "{bad}");
        }
        assert!(check_scale(0.01).is_ok() && check_scale(0.0254).is_ok());
        for bad in [0.0, -0.01, f64::NAN, f64::INFINITY, 1e300, 1e-9] {
            assert!(check_scale(bad).is_err(), "{bad}");
        }
        assert_eq!(resampled_frames(471, 120.0, 60.0), Some(236));
        assert_eq!(resampled_frames(0, 120.0, 60.0), Some(0));
        assert_eq!(resampled_frames(MAX_FRAMES, 1.0, 1000.0), None);
        assert!(check_database_size(100_000, 32, 27).is_ok());
        let e =
            check_database_size(resampled_frames(1_000_000, 1.0, 1000.0).unwrap_or(usize::MAX), 14, 27).unwrap_err();
        assert!(e.contains("frames") && e.len() < 200, "{e}");
    }
}
