//! The hostile-input corpus: malformed BVH cases and `.mmdb` mutations, as pure functions.
//!
//! Shared by the native tests (`tests/hostile_bvh.rs`, `tests/hostile_mmdb.rs`) and the
//! `mmdb-cases` binary, which writes every case to a folder with `cases.json` (the native
//! outcome of each) so that the WASM build can replay the same bytes in Node and compare.
//! Everything is deterministic: cases depend only on the committed seed files and on the
//! fixed PRNG below (xorshift64*, seed per mutation family), never on the clock.

#![allow(dead_code)]

pub mod alloc;

use mmcore::database::{Axes, Clip, Database, FeatureGroup, FeatureKind, Site, Skeleton, Tag};

/// What a case must give. Every case additionally must not panic, hang or over-allocate.
#[derive(Clone, Debug, PartialEq)]
pub enum Expect {
    /// Parses / loads.
    Ok,
    /// An error whose message contains this text.
    Error(String),
    /// Either is fine (random damage that may hit a don't-care byte).
    Either,
}

#[derive(Clone, Debug)]
pub struct Case {
    pub name: String,
    pub bytes: Vec<u8>,
    pub expect: Expect,
}

fn case(name: impl Into<String>, bytes: impl Into<Vec<u8>>, expect: Expect) -> Case {
    Case { name: name.into(), bytes: bytes.into(), expect }
}
fn err(s: &str) -> Expect {
    Expect::Error(s.to_string())
}

/// Deterministic PRNG (xorshift64*), simple enough to port to TypeScript with BigInt.
pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

// ---------------------------------------------------------------------------------------
// BVH

/// A small humanoid the builder accepts (CMU-ASF names): 14 joints, `frames` frames at 120 fps,
/// a slow walk forward with swinging legs. Synthetic, not mocap.
pub fn humanoid_bvh(frames: usize) -> String {
    let mut s = String::from("HIERARCHY\nROOT root\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n");
    let leg = |side: &str, x: f64| {
        format!(
            "  JOINT {side}femur\n  {{\n    OFFSET {x} -0.05 0\n    CHANNELS 3 Zrotation Yrotation Xrotation\n    JOINT {side}tibia\n    {{\n      OFFSET 0 -0.42 0\n      CHANNELS 3 Zrotation Yrotation Xrotation\n      JOINT {side}foot\n      {{\n        OFFSET 0 -0.41 0\n        CHANNELS 3 Zrotation Yrotation Xrotation\n        JOINT {side}toes\n        {{\n          OFFSET 0 -0.05 0.12\n          CHANNELS 3 Zrotation Yrotation Xrotation\n          End Site\n          {{\n            OFFSET 0 0 0.05\n          }}\n        }}\n      }}\n    }}\n  }}\n"
        )
    };
    s += &leg("l", 0.1);
    s += &leg("r", -0.1);
    s += "  JOINT lowerback\n  {\n    OFFSET 0 0.1 0\n    CHANNELS 3 Zrotation Yrotation Xrotation\n    JOINT thorax\n    {\n      OFFSET 0 0.3 0\n      CHANNELS 3 Zrotation Yrotation Xrotation\n      JOINT head\n      {\n        OFFSET 0 0.3 0\n        CHANNELS 3 Zrotation Yrotation Xrotation\n        End Site\n        {\n          OFFSET 0 0.2 0\n        }\n      }\n    }\n  }\n}\n";
    s += &format!("MOTION\nFrames: {frames}\nFrame Time: 0.00833333\n");
    for f in 0..frames {
        let t = f as f64 / 120.0;
        let swing = 25.0 * (t * 6.0).sin();
        let mut v = vec![0.0, 0.95, 1.2 * t, 0.0, 0.0, 0.0];
        for side in [1.0, -1.0] {
            v.extend([0.0, 0.0, side * swing, 0.0, 0.0, (side * swing).max(0.0) * 0.8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
        v.extend([0.0; 9]);
        let line: Vec<String> = v.iter().map(|x| format!("{x:.6}")).collect();
        s += &line.join(" ");
        s += "\n";
    }
    s
}

/// A two-joint file (9 channels, 2 frames).
pub const TWO: &str = "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n  JOINT Chest\n  {\n    OFFSET 0 0.5 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n    End Site\n    {\n      OFFSET 0 0.3 0\n    }\n  }\n}\nMOTION\nFrames: 2\nFrame Time: 0.0333333\n0 1 0 0 0 0 0 0 0\n1 1 0 90 0 0 0 0 45\n";

/// One root joint with 1 channel and the given motion section (after `MOTION\n`).
fn one(motion: &str) -> String {
    format!("HIERARCHY\nROOT x\n{{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}}\nMOTION\n{motion}")
}

/// A flat hierarchy of `n` joints under the root, `Frames: 0`.
pub fn wide(n: usize) -> String {
    let mut s = String::from("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\n");
    for i in 1..n {
        s += &format!("JOINT j{i}\n{{\nOFFSET 0 1 0\n}}\n");
    }
    s + "}\nMOTION\nFrames: 0\nFrame Time: 0.01\n"
}

/// A chain of `n` nested joints, closed, `Frames: 0`.
pub fn deep(n: usize) -> String {
    let mut s = String::from("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\n");
    for i in 1..n {
        s += &format!("JOINT j{i}\n{{\nOFFSET 0 1 0\n");
    }
    s += &"}\n".repeat(n);
    s + "MOTION\nFrames: 0\nFrame Time: 0.01\n"
}

/// The small BVH cases (each well under 64 KiB except the few 1 MB ones; all committed as the
/// fuzzers' seed corpus). Names are file-name safe.
pub fn bvh_cases() -> Vec<Case> {
    let h = humanoid_bvh(12);
    let mut c = vec![
        case("valid_humanoid", h.clone(), Expect::Ok),
        case("valid_two_joints", TWO, Expect::Ok),
        case("valid_utf8_bom", [b"\xEF\xBB\xBF".as_slice(), TWO.as_bytes()].concat(), Expect::Ok),
        case("valid_cr_only", TWO.replace('\n', "\r"), Expect::Ok),
        case("valid_crlf", TWO.replace('\n', "\r\n"), Expect::Ok),
        case("valid_tabs", TWO.replace("  ", "\t"), Expect::Ok),
        case("valid_zero_frames", one("Frames: 0\nFrame Time: 0.01\n"), Expect::Ok),
        case("valid_lowercase_keywords", TWO.to_lowercase().replace("hips", "Hips"), Expect::Ok),
        case("valid_brace_on_name_line", TWO.replace("ROOT Hips\n{", "ROOT Hips {"), Expect::Ok),
        case("valid_exponents", TWO.replace("1 1 0 90", "1e0 1.0E0 0e5 9e1"), Expect::Ok),
        case("valid_underflow_is_zero", TWO.replace("1 1 0 90", "1 1 1e-400 90"), Expect::Ok),
        case("valid_latin1_name", TWO.replace("Chest", "Ch\u{1}st").bytes().map(|b| if b == 1 { 0xE9 } else { b }).collect::<Vec<u8>>(), Expect::Ok),
        case("valid_trailing_blank_lines", format!("{TWO}\n\n  \n"), Expect::Ok),
        case("valid_1000_joints_wide", wide(1000), Expect::Ok),
        case("valid_256_deep", deep(256), Expect::Ok),
        // Encodings and bytes.
        case("empty", "", err("end of file: expected 'HIERARCHY'")),
        case("whitespace_only", " \n\t\r\n", err("expected 'HIERARCHY'")),
        case("utf16le_bom", [vec![0xFF, 0xFE], TWO.encode_utf16().flat_map(|u| u.to_le_bytes()).collect()].concat(), err(":1: the file is UTF-16 (little-endian) text")),
        case("utf16be_bom", [vec![0xFE, 0xFF], TWO.encode_utf16().flat_map(|u| u.to_be_bytes()).collect()].concat(), err(":1: the file is UTF-16 (big-endian) text")),
        case("utf16le_no_bom", TWO.encode_utf16().flat_map(|u| u.to_le_bytes()).collect::<Vec<u8>>(), err(":1: the file is UTF-16")),
        case("utf32le", TWO.chars().flat_map(|ch| (ch as u32).to_le_bytes()).collect::<Vec<u8>>(), err(":1: the file is UTF-32")),
        case("nul_in_keyword", TWO.replacen("HIERARCHY", "HIER\0ARCHY", 1), err(":1: expected 'HIERARCHY', found 'HIER\\0ARCHY'")),
        case("nul_in_value", TWO.replace("1 1 0 90", "1 1 0 9\u{0}0"), err(":20: frame 1: expected a number, found '9\\00'")),
        case("nuls_only", vec![0u8; 4096], err(":1: expected 'HIERARCHY', found '\\0\\0\\0")),
        case("non_utf8_value", [TWO.replace("1 1 0 90", "1 1 0 9\u{1}").as_bytes()].concat().iter().map(|&b| if b == 1 { 0xFF } else { b }).collect::<Vec<u8>>(), err(":20: frame 1: expected a number, found '9\u{fffd}'")),
        case("binary_noise", (0..2048u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect::<Vec<u8>>(), Expect::Either),
        case("bom_then_garbage", [b"\xEF\xBB\xBF".as_slice(), b"HIERARCHX\n"].concat(), err(":1: expected 'HIERARCHY', found 'HIERARCHX'")),
        // Hierarchy.
        case("no_root", "HIERARCHY\nJOINT x\n", err(":2: expected 'ROOT', found 'JOINT'")),
        case("unnamed_joint", "HIERARCHY\nROOT\n{\n", err(":2: joint has no name")),
        case("missing_brace", "HIERARCHY\nROOT x\nOFFSET 0 0 0\n", err(":3: expected '{', found 'OFFSET'")),
        case("no_offset", "HIERARCHY\nROOT x\n{\nCHANNELS 0\n}\n", err(":5: joint 'x' has no OFFSET")),
        case("joint_before_offset", "HIERARCHY\nROOT x\n{\nJOINT y\n", err(":4: joint 'x' needs an OFFSET before its children")),
        case("duplicate_names", TWO.replace("JOINT Chest", "JOINT Hips"), err(":6: duplicate joint name 'Hips'")),
        case("second_channels", TWO.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 1 Zrotation\n    CHANNELS 1 Xrotation"), err(":10: joint 'Chest' has a second CHANNELS line")),
        case("second_root", TWO.replace("}\nMOTION", "}\nROOT y\n{\n}\nMOTION"), err(":16: a second ROOT hierarchy")),
        case("unknown_keyword", TWO.replace("    End Site", "    ROTATION 1 2 3"), err(":10: expected OFFSET, CHANNELS, JOINT, End Site or '}' in joint 'Chest', found 'ROTATION'")),
        case("end_effector", TWO.replace("End Site", "End Effector"), err(":10: expected 'End Site', found 'End Effector'")),
        case("end_site_no_offset", TWO.replace("      OFFSET 0 0.3 0\n", ""), err(":12: expected 'OFFSET', found '}'")),
        case("extra_closing_brace", TWO.replace("}\nMOTION", "}\n}\nMOTION"), err(":16: expected 'MOTION' after the hierarchy, found '}'")),
        case("missing_motion", TWO.replace("MOTION\n", ""), err(":16: expected 'MOTION' after the hierarchy, found 'Frames:'")),
        case("depth_257", deep(257), err(":770: the hierarchy is nested deeper than 256 joints")),
        case("joints_1025", wide(1025), err(":4097: more than 1024 joints")),
        case("long_name", TWO.replace("JOINT Chest", &format!("JOINT {}", "n".repeat(300))), err(":6: joint name 'nnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnnn…' is longer than 256 bytes")),
        // Channels.
        case("channels_7", one("").replace("CHANNELS 1 Xrotation", "CHANNELS 7 Xrotation"), err(":5: CHANNELS count must be 0 to 6, found 7")),
        case("channels_negative", one("").replace("CHANNELS 1 Xrotation", "CHANNELS -1"), err(":5: CHANNELS count must be 0 to 6, found -1")),
        case("channels_fraction", one("").replace("CHANNELS 1 Xrotation", "CHANNELS 1.5 Xrotation"), err(":5: CHANNELS count must be 0 to 6, found 1.5")),
        case("channels_nan", one("").replace("CHANNELS 1 Xrotation", "CHANNELS nan"), err(":5: expected the channel count after 'CHANNELS', found 'nan'")),
        case("channels_too_few_names", TWO.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Xrotation"), err(":10: expected a channel name (Xposition … Zrotation), found 'End'")),
        case("channel_twice", one("").replace("CHANNELS 1 Xrotation", "CHANNELS 2 Xrotation XROTATION"), err(":5: channel RotX listed twice for joint 'x'")),
        case("unknown_channel", one("").replace("Xrotation", "Wrotation"), err(":5: expected a channel name (Xposition … Zrotation), found 'Wrotation'")),
        case("frame_too_few_values", TWO.replace("1 1 0 90 0 0 0 0 45", "1 1 0 90 0 0 0 0"), err(":20: frame 1 has 8 values, expected 9")),
        case("frame_too_many_values", TWO.replace("1 1 0 90 0 0 0 0 45", "1 1 0 90 0 0 0 0 45 7"), err(":20: frame 1 has 10 values, expected 9")),
        case("frame_values_split_over_lines", TWO.replace("1 1 0 90 0 0 0 0 45", "1 1 0 90\n0 0 0 0 45"), err(":20: frame 1 has 4 values, expected 9")),
        // Values.
        case("value_nan", TWO.replace("1 1 0 90", "1 1 0 nan"), err(":20: frame 1: expected a number, found 'nan' (column 7)")),
        case("value_inf", TWO.replace("1 1 0 90", "1 1 0 inf"), err(":20: frame 1: expected a number, found 'inf'")),
        case("value_minus_infinity", TWO.replace("1 1 0 90", "1 1 0 -infinity"), err(":20: frame 1: expected a number, found '-infinity'")),
        case("value_1e308", TWO.replace("1 1 0 90", "1 1 0 1e308"), err(":20: frame 1: value 1e308 at column 7 is out of range")),
        case("value_1e39", TWO.replace("1 1 0 90", "1 1 0 1e39"), err(":20: frame 1: value 1e39 at column 7 is out of range")),
        case("value_overflow_1e400", TWO.replace("1 1 0 90", "1 1 0 1e400"), err(":20: frame 1: expected a number, found '1e400'")),
        case("value_just_too_big", TWO.replace("1 1 0 90", "1 1 0 10000000.5"), err(":20: frame 1: value 1.00000005e7 at column 7 is out of range")),
        case("value_long_digits", TWO.replace("1 1 0 90", "1 1 0 99999999999999999999999"), err(":20: frame 1: value 1e23 at column 7 is out of range")),
        case("value_hex", TWO.replace("1 1 0 90", "1 1 0 0x5A"), err(":20: frame 1: expected a number, found '0x5A'")),
        case("value_comma", TWO.replace("1 1 0 90", "1 1 0 9,5"), err(":20: frame 1: expected a number, found '9,5'")),
        case("offset_1e300", TWO.replace("OFFSET 0 0.5 0", "OFFSET 0 1e300 0"), err(":8: OFFSET y is 1e300, out of range (magnitude ≤ 1e7)")),
        case("offset_nan", TWO.replace("OFFSET 0 0.5 0", "OFFSET nan 0.5 0"), err(":8: expected OFFSET x, found 'nan'")),
        case("end_site_offset_inf", TWO.replace("OFFSET 0 0.3 0", "OFFSET 0 inf 0"), err(":12: expected End Site OFFSET y, found 'inf'")),
        case("token_1mb_value", TWO.replace("1 1 0 90", &format!("1 1 0 {}", "9".repeat(1 << 20))), err(":20: frame 1: expected a number, found '9999999999999999999999999999999999999999…' (column 7)")),
        case("token_1mb_junk", TWO.replace("1 1 0 90", &format!("1 1 0 {}", "x".repeat(1 << 20))), err(":20: frame 1: expected a number, found 'xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx…' (column 7)")),
        case("token_1mb_keyword", format!("HIERARCHY\nROOT x\n{{\n{}\n", "K".repeat(1 << 20)), err(":4: expected OFFSET, CHANNELS, JOINT, End Site or '}' in joint 'x', found 'KKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKKK…'")),
        // Frames:
        case("frames_negative", one("Frames: -1\nFrame Time: 0.01\n"), err(":8: 'Frames:' must be a whole number from 0 to 16777216, found '-1'")),
        case("frames_fraction", one("Frames: 2.5\nFrame Time: 0.01\n"), err(":8: 'Frames:' must be a whole number from 0 to 16777216, found '2.5'")),
        case("frames_2pow31", one("Frames: 2147483648\nFrame Time: 0.01\n0\n"), err(":8: 'Frames:' must be a whole number from 0 to 16777216, found '2147483648'")),
        case("frames_1e9", one("Frames: 1000000000\nFrame Time: 0.01\n0\n"), err(":8: 'Frames:' must be a whole number")),
        case("frames_1e19", one("Frames: 1e19\nFrame Time: 0.01\n0\n"), err(":8: 'Frames:' must be a whole number")),
        case("frames_1e300", one("Frames: 1e300\nFrame Time: 0.01\n0\n"), err(":8: 'Frames:' must be a whole number")),
        case("frames_nan", one("Frames: NaN\nFrame Time: 0.01\n0\n"), err(":8: 'Frames:' must be a whole number from 0 to 16777216, found 'NaN'")),
        case("frames_word", one("Frames: many\nFrame Time: 0.01\n0\n"), err(":8: 'Frames:' must be a whole number from 0 to 16777216, found 'many'")),
        case("frames_max_in_tiny_file", one("Frames: 16777216\nFrame Time: 0.01\n0\n"), err("end of file: 'Frames:' on line 8 declares 16777216 frames but only 1 frame lines follow")),
        case("frames_more_lines", one("Frames: 1\nFrame Time: 0.01\n0\n1\n"), err(":11: more frame lines than the 1 declared by 'Frames:' on line 8")),
        case("frames_fewer_lines", one("Frames: 3\nFrame Time: 0.01\n0\n1\n"), err("end of file: 'Frames:' on line 8 declares 3 frames but only 2 frame lines follow")),
        case("frames_missing_count", one("Frames:"), err(":8: unexpected end of file: expected the frame count after 'Frames:'")),
        // Frame Time:
        case("frame_time_zero", one("Frames: 1\nFrame Time: 0\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds (10000 to 1 fps), found '0'")),
        case("frame_time_negative", one("Frames: 1\nFrame Time: -0.01\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds")),
        case("frame_time_1e-300", one("Frames: 1\nFrame Time: 1e-300\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds")),
        case("frame_time_1e300", one("Frames: 1\nFrame Time: 1e300\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds")),
        case("frame_time_nan", one("Frames: 1\nFrame Time: nan\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds (10000 to 1 fps), found 'nan'")),
        case("frame_time_inf", one("Frames: 1\nFrame Time: inf\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds")),
        case("frame_time_2s", one("Frames: 1\nFrame Time: 2\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds")),
        case("frame_time_1e-5", one("Frames: 1\nFrame Time: 0.00001\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds")),
        case("frame_time_word", one("Frames: 1\nFrame Time: fast\n0\n"), err(":9: 'Frame Time:' must be 0.0001 to 1 seconds (10000 to 1 fps), found 'fast'")),
        case("frame_time_missing", one("Frames: 1\nTime: 0.01\n0\n"), err(":9: expected 'Frame', found 'Time:'")),
        case("frame_time_misspelt", one("Frames: 1\nFrame Tme: 0.01\n0\n"), err(":9: expected 'Frame Time:', found 'Frame Tme:'")),
    ];
    // Truncation after every line of the humanoid (each section, each joint, each frame).
    let lines: Vec<&str> = h.split_inclusive('\n').collect();
    for k in 0..lines.len() - 1 {
        c.push(case(format!("truncated_after_line_{:03}", k + 1), lines[..=k].concat(), err("end of file")));
    }
    // Mid-token truncations of the two-joint file.
    for (k, cut) in [
        "HIERAR",
        "HIERARCHY\nROOT Hi",
        "OFFSET 0 0.",
        "CHANNELS 6 Xpos",
        "End Si",
        "Frames: ",
        "Frame Time: 0.03",
        "0 1 0 0 0 0 0 0 0\n1 1 0 9",
    ]
    .iter()
    .enumerate()
    {
        let at = TWO.find(cut).unwrap() + cut.len();
        c.push(case(format!("truncated_mid_token_{k}"), &TWO.as_bytes()[..at], Expect::Either));
    }
    c
}

/// Tokens the random mutator splices in: the values and keywords parsers trip on.
pub const DICTIONARY: [&str; 16] = [
    "nan",
    "1e308",
    "-1",
    "{",
    "}",
    "JOINT x\n{\n",
    "End Site",
    "\r",
    "\0",
    "Frames: 16777216",
    "CHANNELS 6",
    "\u{feff}",
    "OFFSET 0 0 0\n",
    "1e39",
    "Frame Time: 1e-300",
    "\n",
];

/// One random mutation of `input` (deterministic in `rng`): 1–2 of bit flip, interesting byte,
/// deleted range, duplicated range, dictionary token inserted or replacing a token.
pub fn mutate(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = input.to_vec();
    for _ in 0..1 + rng.below(2) {
        let n = b.len();
        match rng.below(6) {
            0 if n > 0 => {
                let at = rng.below(n);
                b[at] ^= 1 << rng.below(8);
            }
            1 if n > 0 => {
                let at = rng.below(n);
                b[at] = b"\0\xFF\n\r {}-.e9"[rng.below(11)];
            }
            2 if n > 0 => {
                let at = rng.below(n);
                let len = rng.below(64).min(n - at);
                b.drain(at..at + len);
            }
            3 if n > 0 => {
                let at = rng.below(n);
                let len = rng.below(256).min(n - at);
                let piece = b[at..at + len].to_vec();
                let to = rng.below(n + 1);
                b.splice(to..to, piece);
            }
            4 => {
                let to = rng.below(n + 1);
                b.splice(to..to, DICTIONARY[rng.below(DICTIONARY.len())].bytes());
            }
            _ if n > 0 => {
                // Replace the whitespace-delimited token around a random position.
                let at = rng.below(n);
                let start = b[..at].iter().rposition(|c| c.is_ascii_whitespace()).map_or(0, |p| p + 1);
                let end = b[at..].iter().position(|c| c.is_ascii_whitespace()).map_or(n, |p| at + p);
                b.splice(start..end, DICTIONARY[rng.below(DICTIONARY.len())].bytes());
            }
            _ => b.extend_from_slice(DICTIONARY[rng.below(DICTIONARY.len())].as_bytes()),
        }
    }
    b
}

/// Big cases, generated in the test (never committed): depth, width, a 200 MB file.
pub fn big_bvh_cases() -> Vec<Case> {
    vec![
        case("deep_5k", deep(5_000), err(":770: the hierarchy is nested deeper than 256 joints")),
        case("deep_20k", deep(20_000), err(":770: the hierarchy is nested deeper than 256 joints")),
        case("deep_100k", deep(100_000), err(":770: the hierarchy is nested deeper than 256 joints")),
        case(
            "deep_100k_unclosed",
            deep(100_000).split("}\n").next().unwrap().to_string(),
            err(":770: the hierarchy is nested deeper than 256 joints"),
        ),
        case("wide_10k", wide(10_000), err(":4097: more than 1024 joints")),
        case(
            "name_1mb",
            format!("HIERARCHY\nROOT {}\n{{\n", "N".repeat(1 << 20)),
            err(":2: joint name 'NNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNNN…' is longer than 256 bytes"),
        ),
        case(
            "frames_claim_max_1mb_file",
            {
                let mut s = one("Frames: 16777216\nFrame Time: 0.01\n");
                s += &"0\n".repeat(1 << 19);
                s
            },
            err("declares 16777216 frames but only 524288 frame lines follow"),
        ),
    ]
}

/// A valid ~200 MB BVH (the humanoid's hierarchy, many frames), for the size test.
pub fn huge_valid_bvh(target_bytes: usize) -> Vec<u8> {
    let head = humanoid_bvh(0);
    let line = {
        let h = humanoid_bvh(2);
        h.lines().last().unwrap().to_string() + "\n"
    };
    let frames = (target_bytes - head.len()) / line.len();
    let mut out = Vec::with_capacity(head.len() + frames * line.len());
    out.extend_from_slice(head.replace("Frames: 0", &format!("Frames: {frames}")).as_bytes());
    for _ in 0..frames {
        out.extend_from_slice(line.as_bytes());
    }
    out
}

// ---------------------------------------------------------------------------------------
// .mmdb

/// A tiny but complete handmade database (2 joints, 4 frames, 2 clips one mirrored, a tag,
/// two feature groups) — independent of the builder, so its bytes never drift.
pub fn tiny_database() -> Database {
    Database {
        skeleton: Skeleton {
            names: vec!["VirtualRoot".into(), "Hips".into()],
            parents: vec![-1, 0],
            offsets: vec![glam::Vec3::ZERO, glam::Vec3::Y],
            sites: vec![Site { name: "hips".into(), joint: 1, offset: glam::Vec3::ZERO }],
            mirror: vec![0, 1],
        },
        fps: 60.0,
        num_frames: 4,
        clips: vec![
            Clip {
                name: "a".into(),
                source: "a.bvh".into(),
                start: 0,
                end: 2,
                mirrored: false,
                source_fps: 120.0,
                scale: 0.01,
                root_scale: 1.0,
                source_start: 0,
            },
            Clip {
                name: "a (mirror)".into(),
                source: "a.bvh".into(),
                start: 2,
                end: 4,
                mirrored: true,
                source_fps: 120.0,
                scale: 0.01,
                root_scale: 1.0,
                source_start: 0,
            },
        ],
        tags: vec![Tag { name: "walk".into(), ranges: vec![(0, 1), (2, 4)] }],
        local_positions: (0..8).map(|i| glam::Vec3::splat(i as f32 * 0.1)).collect(),
        local_rotations: (0..8).map(|i| glam::Quat::from_rotation_y(i as f32 * 0.2)).collect(),
        contacts: vec![1, 0, 0, 1, 1, 1, 0, 0],
        groups: vec![
            FeatureGroup {
                name: "p".into(),
                kind: FeatureKind::Position,
                is_trajectory: true,
                axes: Axes::Xz,
                joint: 0,
                axis: glam::Vec3::Z,
                offsets: vec![1],
                weight: 1.0,
                first_dim: 0,
                num_dims: 2,
            },
            FeatureGroup {
                name: "v".into(),
                kind: FeatureKind::Velocity,
                is_trajectory: false,
                axes: Axes::Xyz,
                joint: 1,
                axis: glam::Vec3::Z,
                offsets: vec![0],
                weight: 0.5,
                first_dim: 2,
                num_dims: 3,
            },
        ],
        feature_mean: vec![0.5, 0.25, 0.0, 0.0, 0.0],
        feature_scale: vec![2.0, 2.0, 1.0, 1.0, 1.0],
        features: (0..20).map(|i| i as f32 * 0.1 - 1.0).collect(),
        valid: vec![1, 0, 1, 0],
        part: None,
        velocities: Default::default(),
    }
}

/// [`tiny_database`] with a group of `extra` more dimensions (xz at `extra / 2` offsets): 128
/// more makes 133, past what the search takes (issue 28: such a file loaded and nothing could
/// search it).
pub fn wide_database(extra: usize) -> Database {
    let mut db = tiny_database();
    let d = db.num_features();
    let group = FeatureGroup {
        name: "wide".into(),
        offsets: vec![0; extra / 2],
        first_dim: d,
        num_dims: extra / 2 * 2,
        ..db.groups[0].clone()
    };
    let extra = group.num_dims;
    db.groups.push(group);
    db.feature_mean.resize(d + extra, 0.0);
    db.feature_scale.resize(d + extra, 1.0);
    db.features =
        db.features.chunks(d).flat_map(|row| row.iter().copied().chain(std::iter::repeat_n(0.0, extra))).collect();
    db
}

/// The `.mmdb` cases of the issue, by name, each with the message the loader must give
/// (all with a valid checksum: the damage is what the loader must see).
pub fn mmdb_named_cases() -> Vec<Case> {
    let tiny = tiny_database();
    let bytes = mmcore::format::to_bytes(&tiny);
    let t = table(&bytes);
    let at = |tag: &[u8; 4]| t.iter().find(|e| &e.0 == tag).copied().unwrap();
    let edit = |f: &dyn Fn(&mut Database)| {
        let mut db = tiny_database();
        f(&mut db);
        mmcore::format::to_bytes(&db)
    };
    let patched = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = bytes.clone();
        f(&mut b);
        refix(&mut b);
        b
    };
    let info = at(b"INFO").2;
    vec![
        // One flipped exponent bit: 60 fps → 1.1e21 fps froze the page.
        case(
            "fps_bit_flip",
            patched(&|b| b[info + 11] ^= 0x20),
            err("INFO.fps must be between 1 and 1000, found 1.10680464e21"),
        ),
        case(
            "fps_zero",
            patched(&|b| b[info + 8..info + 12].copy_from_slice(&0f32.to_le_bytes())),
            err("INFO.fps must be between 1 and 1000, found 0"),
        ),
        case(
            "zero_feature_groups",
            edit(&|db| {
                db.groups.clear();
                db.feature_mean.clear();
                db.feature_scale.clear();
                db.features.clear();
            }),
            err("INFO has 0 feature groups and 0 feature dims"),
        ),
        case(
            "empty_last_group",
            edit(&|db| {
                db.groups[1].offsets.clear();
                db.groups[1].num_dims = 0;
                db.feature_mean.truncate(2);
                db.feature_scale.truncate(2);
                db.features = db.features.chunks(5).flat_map(|r| r[..2].to_vec()).collect();
            }),
            err("FDSC: feature 'v' has no frame offsets"),
        ),
        case(
            "zero_frames",
            patched(&|b| b[info..info + 4].copy_from_slice(&0u32.to_le_bytes())),
            err("INFO.num_frames is 0"),
        ),
        case("nan_feature_scale", edit(&|db| db.feature_scale[0] = f32::NAN), err("FNRM: scale of dim 0 is NaN")),
        case("zero_clip_scale", edit(&|db| db.clips[0].scale = 0.0), err("CLIP 'a': scale 0 is outside")),
        case("nan_position", edit(&|db| db.local_positions[1].x = f32::NAN), err("PANM: value 3 is NaN")),
        case(
            "huge_derived_feature",
            edit(&|db| {
                // Every stored value in bounds; the feature derived from them (a root 1e11 m
                // away over a scale of 1e-3) is not.
                db.local_positions[2].x = 1e11;
                db.feature_scale[0] = 1e-3;
            }),
            err("features derived from PANM and QROT: value 0 is"),
        ),
        case(
            "section_count_huge",
            patched(&|b| b[12..16].copy_from_slice(&u32::MAX.to_le_bytes())),
            err("section table of 4294967295 entries runs past the end"),
        ),
        case(
            "section_length_huge",
            patched(&|b| {
                let e = at(b"VALD").1;
                b[e + 16..e + 24].copy_from_slice(&u64::MAX.to_le_bytes())
            }),
            err("section VALD (offset"),
        ),
        case(
            "sections_overlap",
            patched(&|b| {
                let (lpos, lvel) = (at(b"PANM").1, at(b"QROT").1);
                let off: [u8; 8] = b[lpos + 8..lpos + 16].try_into().unwrap();
                b[lvel + 8..lvel + 16].copy_from_slice(&off);
            }),
            err("sections QROT and PANM overlap"),
        ),
        case(
            "clip_count_huge",
            patched(&|b| {
                let c = at(b"CLIP").2;
                b[c..c + 4].copy_from_slice(&u32::MAX.to_le_bytes())
            }),
            err("CLIP clip count 4294967295 does not fit in the section"),
        ),
        case("valid_tiny", bytes.clone(), Expect::Ok),
    ]
}

/// Section table of a `.mmdb`: (tag, entry offset in the file, data offset, data length).
pub fn table(bytes: &[u8]) -> Vec<([u8; 4], usize, usize, usize)> {
    let count = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    (0..count)
        .map(|i| {
            let e = 32 + 24 * i;
            let tag: [u8; 4] = bytes[e..e + 4].try_into().unwrap();
            let off = u64::from_le_bytes(bytes[e + 8..e + 16].try_into().unwrap()) as usize;
            let len = u64::from_le_bytes(bytes[e + 16..e + 24].try_into().unwrap()) as usize;
            (tag, e, off, len)
        })
        .collect()
}

/// Rewrites `file_size` and the CRC so that a deliberate edit is what the loader sees.
pub fn refix(bytes: &mut [u8]) {
    let n = bytes.len() as u64;
    if bytes.len() >= 32 {
        bytes[16..24].copy_from_slice(&n.to_le_bytes());
        let crc = crc32fast::hash(&bytes[32..]);
        bytes[24..28].copy_from_slice(&crc.to_le_bytes());
    }
}

fn put(bytes: &mut [u8], at: usize, v: &[u8]) {
    if at + v.len() <= bytes.len() {
        bytes[at..at + v.len()].copy_from_slice(v);
    }
}

/// Byte offsets of every f32 field of the small sections worth poisoning: INFO.fps, each
/// clip's source fps / scale / root scale, each group's weight, and the FNRM scales.
fn float_fields(bytes: &[u8]) -> Vec<(String, usize, usize)> {
    let t = table(bytes);
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    let find = |tag: &[u8; 4]| t.iter().find(|e| &e.0 == tag).map(|e| (e.2, e.3));
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let mut out = Vec::new();
    if let Some((info, _)) = find(b"INFO") {
        out.push(("INFO.fps".to_string(), info + 8, 4));
    }
    if let Some((clip, _)) = find(b"CLIP") {
        let mut p = clip + 4;
        for i in 0..u32_at(clip).min(4) {
            p += 4 + u32_at(p);
            p += 4 + u32_at(p);
            p += 9;
            // Version 2 stores the source rate as f64 and appends the u32 source start.
            let fps_len = if version == 1 { 4 } else { 8 };
            out.push((format!("CLIP[{i}].source_fps"), p, fps_len));
            for (k, f) in ["scale", "root_scale"].iter().enumerate() {
                out.push((format!("CLIP[{i}].{f}"), p + fps_len + 4 * k, 4));
            }
            p += fps_len + 8 + if version == 1 { 0 } else { 4 };
        }
    }
    if let Some((fdsc, _)) = find(b"FDSC") {
        let mut p = fdsc + 4;
        for i in 0..u32_at(fdsc).min(4) {
            p += 4 + u32_at(p) + 8;
            out.push((format!("FDSC[{i}].axis.x"), p, 4));
            p += 12;
            p += 4 + 4 * u32_at(p);
            out.push((format!("FDSC[{i}].weight"), p, 4));
            p += 12;
        }
    }
    if let Some((fnrm, len)) = find(b"FNRM") {
        let d = len / 8;
        out.push(("FNRM.mean[0]".into(), fnrm, 4));
        for k in 0..d.min(3) {
            out.push((format!("FNRM.scale[{k}]"), fnrm + 4 * (d + k), 4));
        }
    }
    // Version 1 only: version 2's arrays are not plain f32 (a NaN pattern written there is
    // not a NaN value; codec.rs validates what they decode to).
    for tag in [b"LPOS", b"LROT", b"FEAT"] {
        if let Some((off, _)) = find(tag) {
            out.push((format!("{}[0]", String::from_utf8_lossy(tag)), off, 4));
        }
    }
    out
}

/// The deterministic mutation list of one seed file (`seed_name` prefixes case names).
///
/// Families (each a pure function of the seed bytes): `trunc` (every 16th length of the first
/// KiB, each section's start and end, 64 even steps; ±1 each; raw and with size/CRC rewritten), `flip` (every bit of the header, table and INFO with the CRC
/// rewritten; 256 random bits raw and 256 with CRC), `field` (table offsets/lengths, INFO counts
/// and section-internal counts set to 0, 1, huge), `swap` (every pair of table entries' tags
/// and their offsets), `float` (each float field set to NaN, ±∞, 0, −0, 1e30, a denormal),
/// `damage` (1–8 random bytes replaced, raw and with CRC).
pub fn mmdb_mutations(seed_name: &str, seed: &[u8]) -> Vec<Case> {
    let mut out = Vec::new();
    let mut add = |name: String, bytes: Vec<u8>, expect: Expect| {
        out.push(Case { name: format!("{seed_name}.{name}"), bytes, expect })
    };
    let n = seed.len();
    let t = table(seed);
    let header_and_table = 32 + 24 * t.len();
    let info = t.iter().find(|e| &e.0 == b"INFO").map(|e| e.2).unwrap_or(0);

    // Truncations.
    let mut lengths: Vec<usize> = (0..n.min(1024))
        .step_by(16)
        .chain(t.iter().flat_map(|e| [e.2, e.2 + e.3]))
        .flat_map(|k| [k, k + 1, k.saturating_sub(1)])
        .chain((0..64).map(|i| i * n / 64))
        .filter(|&k| k < n)
        .collect();
    lengths.sort_unstable();
    lengths.dedup();
    for &k in &lengths {
        add(format!("trunc.raw.{k}"), seed[..k].to_vec(), Expect::Error(String::new()));
        let mut b = seed[..k].to_vec();
        refix(&mut b);
        // Cutting only the zero padding after the last section still loads.
        add(format!("trunc.fixed.{k}"), b, Expect::Either);
    }
    // Exhaustive bit flips of header + table + INFO, CRC rewritten (the size field too, but
    // refix rewrites it, so flips of 16..28 are checked raw instead).
    for byte in (0..header_and_table).chain(info..info + 32) {
        for bit in 0..8 {
            let mut b = seed.to_vec();
            b[byte] ^= 1 << bit;
            if !(16..28).contains(&byte) {
                refix(&mut b);
            }
            add(format!("flip.fixed.{byte}.{bit}"), b, Expect::Either);
        }
    }
    // Random bit flips anywhere: raw (must fail the checksum) and CRC rewritten.
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ n as u64);
    for i in 0..256 {
        let (byte, bit) = (32 + rng.below(n - 32), rng.below(8));
        let mut b = seed.to_vec();
        b[byte] ^= 1 << bit;
        add(format!("flip.raw.{i}.{byte}.{bit}"), b.clone(), err("checksum mismatch"));
        refix(&mut b);
        add(format!("flip.fixed.rand.{i}.{byte}.{bit}"), b, Expect::Either);
    }
    // Table fields and counts set to extremes.
    let huge64: [u64; 6] = [0, 1, n as u64, 1 << 32, 1 << 40, u64::MAX];
    for (i, e) in t.iter().enumerate() {
        for (k, v) in huge64.iter().enumerate() {
            for (field, at) in [("offset", e.1 + 8), ("length", e.1 + 16)] {
                let mut b = seed.to_vec();
                put(&mut b, at, &v.to_le_bytes());
                refix(&mut b);
                add(format!("field.table{i}.{field}.{k}"), b, Expect::Either);
            }
        }
    }
    let huge32: [u32; 5] = [0, 1, 1 << 31, u32::MAX - 1, u32::MAX];
    let mut counts: Vec<(String, usize)> = vec![("header.section_count".into(), 12)];
    for (k, f) in ["num_frames", "num_joints", "fps", "num_dims", "num_clips", "num_tags", "num_groups", "flags"]
        .iter()
        .enumerate()
    {
        counts.push((format!("INFO.{f}"), info + 4 * k));
    }
    for e in &t {
        if [b"SKEL", b"CLIP", b"TAGS", b"FDSC"].contains(&&e.0) && e.3 >= 4 {
            let tag = String::from_utf8_lossy(&e.0).into_owned();
            counts.push((format!("{tag}.first_u32"), e.2));
            counts.push((format!("{tag}.last_u32"), e.2 + e.3 - 4));
        }
    }
    for (name, at) in &counts {
        for (k, v) in huge32.iter().enumerate() {
            let mut b = seed.to_vec();
            put(&mut b, *at, &v.to_le_bytes());
            refix(&mut b);
            add(format!("field.{name}.{k}"), b, Expect::Either);
        }
    }
    // Swapped sections: tags exchanged (data stays), and whole entries' offsets exchanged.
    for i in 0..t.len() {
        for j in i + 1..t.len() {
            let mut b = seed.to_vec();
            b[t[i].1..t[i].1 + 4].copy_from_slice(&t[j].0);
            b[t[j].1..t[j].1 + 4].copy_from_slice(&t[i].0);
            refix(&mut b);
            add(format!("swap.tags.{i}.{j}"), b, Expect::Either);
            let mut b = seed.to_vec();
            let (ei, ej) = (seed[t[i].1 + 8..t[i].1 + 24].to_vec(), seed[t[j].1 + 8..t[j].1 + 24].to_vec());
            b[t[i].1 + 8..t[i].1 + 24].copy_from_slice(&ej);
            b[t[j].1 + 8..t[j].1 + 24].copy_from_slice(&ei);
            refix(&mut b);
            add(format!("swap.entries.{i}.{j}"), b, Expect::Either);
        }
    }
    // Float fields poisoned.
    let poisons: [(&str, f32); 7] = [
        ("nan", f32::NAN),
        ("inf", f32::INFINITY),
        ("-inf", f32::NEG_INFINITY),
        ("zero", 0.0),
        ("-zero", -0.0),
        ("1e30", 1e30),
        ("denormal", 1e-40),
    ];
    for (field, at, len) in float_fields(seed) {
        for (pname, v) in poisons {
            let mut b = seed.to_vec();
            put(&mut b, at, &if len == 8 { (v as f64).to_le_bytes().to_vec() } else { v.to_le_bytes().to_vec() });
            refix(&mut b);
            let expect = match (field.as_str(), pname) {
                (_, "nan" | "inf" | "-inf") => Expect::Error(String::new()),
                ("INFO.fps", _) => Expect::Error("INFO.fps".into()),
                (f, "zero" | "-zero" | "denormal")
                    if f.starts_with("FNRM.scale")
                        || f.ends_with("weight")
                        || f.contains("scale")
                        || f.contains("fps") =>
                {
                    Expect::Error(String::new())
                }
                _ => Expect::Either,
            };
            add(format!("float.{field}.{pname}"), b, expect);
        }
    }
    // Random damage: 1–8 bytes replaced.
    let mut rng = Rng(0xD1B5_4A32_D192_ED03 ^ n as u64);
    for i in 0..150 {
        let mut b = seed.to_vec();
        for _ in 0..1 + rng.below(8) {
            let at = rng.below(n);
            b[at] = rng.next() as u8;
        }
        add(format!("damage.raw.{i}"), b.clone(), Expect::Either);
        refix(&mut b);
        add(format!("damage.fixed.{i}"), b, Expect::Either);
    }
    out
}
