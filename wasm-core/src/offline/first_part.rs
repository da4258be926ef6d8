//! The first part of a database (docs/mmdb-format.md, `PART`): a few of its clips, chosen so
//! that a page's first seconds look natural (standing, walking, turning, stepping aside and
//! back), written beside the whole so that a page draws its first frame after a small share of
//! the bytes and moves to the whole when it has arrived (docs/database.md, "First part").
//!
//! Whole clips only, with everything per frame copied: a frame's features, validity and
//! derived velocities depend on its clip (clamped offsets, one-sided differences at the ends),
//! so a window of a clip would not be the same frame as in the whole, and the swap would show.

use crate::character::{start_frame, CharacterSettings};
use crate::database::{Database, Part, Tag};
use crate::error::{Error, Result};
use serde::Deserialize;

/// What the first part holds (`first_part` in a build config).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FirstPartSpec {
    /// At most this many seconds of motion: its bytes grow with it (the default locomotion
    /// database's frames are ~150 bytes each brotli-compressed).
    pub seconds: f64,
    /// The tags to cover, the most needed first: clips are taken in turns, one per tag (see
    /// [`choose`]). A clip's mirrored copy comes with it.
    pub tags: Vec<String>,
    /// No clip with a frame under any of these (e.g. the styles a character does not start in).
    #[serde(default)]
    pub exclude: Vec<String>,
}

/// Most seconds a first part may ask for (an hour: far more than any first part needs).
pub const MAX_SECONDS: f64 = 3600.0;

impl FirstPartSpec {
    /// # Errors
    /// [`Error::Config`] for `seconds` outside (0, [`MAX_SECONDS`]] or no tags.
    pub fn validate(&self) -> Result<()> {
        if !(self.seconds > 0.0 && self.seconds <= MAX_SECONDS) {
            return Err(Error::config(format!(
                "first_part.seconds must be above 0 and at most {MAX_SECONDS}, found {}",
                self.seconds
            )));
        }
        if self.tags.is_empty() {
            return Err(Error::config("first_part.tags must name at least one tag"));
        }
        Ok(())
    }
}

/// The clip's name without its ` (mirror)` suffix: a clip and its mirrored copy go together.
fn pair_name(name: &str) -> &str {
    name.strip_suffix(" (mirror)").unwrap_or(name)
}

/// Frames of `[start, end)` under `tag`'s ranges.
fn overlap(tag: &Tag, start: u32, end: u32) -> u32 {
    tag.ranges.iter().map(|&(s, e)| e.min(end).saturating_sub(s.max(start))).sum()
}

/// The clips of the first part (indices into `db.clips`, ascending): the clip pair a new
/// character starts on, then, by tag: each tag of
/// `spec.tags` has a quota, an equal share of `spec.seconds`. In turns over the tags, a tag
/// short of its quota adds the clip pair (a clip and its mirrored copy) that brings the most
/// of what it lacks, the shorter on a tie, among those not taken, free of `spec.exclude` and
/// fitting in what is left; frames count toward every tag they carry. It stops when a whole
/// round adds nothing.
///
/// # Errors
/// [`Error::Config`] naming a tag the database does not have, or when no clip fits.
pub fn choose(db: &Database, spec: &FirstPartSpec) -> Result<Vec<usize>> {
    let find = |names: &[String]| {
        names
            .iter()
            .map(|name| {
                db.tags.iter().find(|t| &t.name == name).ok_or_else(|| {
                    let have: Vec<&str> = db.tags.iter().map(|t| t.name.as_str()).collect();
                    Error::config(format!("first_part: no tag '{name}' in the database (it has {})", have.join(", ")))
                })
            })
            .collect::<Result<Vec<_>>>()
    };
    let (tags, exclude) = (find(&spec.tags)?, find(&spec.exclude)?);
    let excluded = |i: usize| exclude.iter().any(|t| overlap(t, db.clips[i].start, db.clips[i].end) > 0);
    // Clip pairs, in clip order.
    let mut pairs: Vec<(&str, Vec<usize>)> = Vec::new();
    for (i, c) in db.clips.iter().enumerate() {
        let key = pair_name(&c.name);
        match pairs.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(i),
            None => pairs.push((key, vec![i])),
        }
    }
    let frames_of = |members: &[usize]| -> u32 { members.iter().map(|&i| db.clips[i].end - db.clips[i].start).sum() };
    let under = |tag: &Tag, members: &[usize]| -> u32 {
        members.iter().map(|&i| overlap(tag, db.clips[i].start, db.clips[i].end)).sum()
    };
    let budget = (spec.seconds * f64::from(db.fps)).floor() as u32;
    let quota = budget / tags.len() as u32;
    let (mut taken, mut used) = (vec![false; pairs.len()], 0u32);
    let mut covered = vec![0u32; tags.len()];
    // Takes pair `p`: its frames count toward the budget and toward every tag they carry.
    let take = |p: usize, taken: &mut [bool], used: &mut u32, covered: &mut [u32]| {
        taken[p] = true;
        *used += frames_of(&pairs[p].1);
        for (c, t) in covered.iter_mut().zip(&tags) {
            *c += under(t, &pairs[p].1);
        }
    };
    // First the clip a new character starts on (`character::start_frame`, default settings): the
    // part then opens on the very pose the whole does, and a visitor sees the same first frame.
    let start = db.clip_at(start_frame(db, &CharacterSettings::default()));
    if let Some(p) = pairs.iter().position(|(_, members)| members.contains(&start)) {
        if frames_of(&pairs[p].1) <= budget {
            take(p, &mut taken, &mut used, &mut covered);
        }
    }
    loop {
        let mut added = false;
        for (k, tag) in tags.iter().enumerate() {
            let lacking = quota.saturating_sub(covered[k]);
            if lacking == 0 {
                continue;
            }
            let mut best: Option<(usize, i64, u32)> = None;
            for (p, (_, members)) in pairs.iter().enumerate() {
                let n = frames_of(members);
                if taken[p] || n == 0 || used + n > budget || members.iter().any(|&i| excluded(i)) {
                    continue;
                }
                // What it brings less what it costs beyond that: a long clip with a little of
                // the tag loses to a short one that is all of it.
                let brings = under(tag, members).min(lacking);
                let score = 2 * i64::from(brings) - i64::from(n);
                if brings > 0 && best.is_none_or(|(_, b, m)| score > b || (score == b && n < m)) {
                    best = Some((p, score, n));
                }
            }
            if let Some((p, _, _)) = best {
                take(p, &mut taken, &mut used, &mut covered);
                added = true;
            }
        }
        if !added {
            break;
        }
    }
    let mut clips: Vec<usize> =
        pairs.iter().zip(&taken).filter(|(_, &t)| t).flat_map(|((_, members), _)| members.iter().copied()).collect();
    clips.sort_unstable();
    if clips.is_empty() {
        return Err(Error::config(format!("first_part: no clip with those tags fits in {} s", spec.seconds)));
    }
    Ok(clips)
}

/// The database made of `clips` (ascending indices into `whole.clips`) of `whole`, everything
/// per frame and the feature normalization copied, marked as the first part of the file
/// `whole_name` whose header checksum is `whole_checksum`.
pub fn cut(whole: &Database, clips: &[usize], whole_name: &str, whole_checksum: u32) -> Result<Database> {
    if !Part::is_plain_name(whole_name) {
        return Err(Error::config(format!("the whole's file name '{whole_name}' is not a plain file name")));
    }
    let (j, d) = (whole.num_joints(), whole.num_features());
    let mut db = Database {
        skeleton: whole.skeleton.clone(),
        fps: whole.fps,
        num_frames: 0,
        clips: Vec::with_capacity(clips.len()),
        tags: whole.tags.iter().map(|t| Tag { name: t.name.clone(), ranges: Vec::new() }).collect(),
        local_positions: Vec::new(),
        local_rotations: Vec::new(),
        contacts: Vec::new(),
        groups: whole.groups.clone(),
        feature_mean: whole.feature_mean.clone(),
        feature_scale: whole.feature_scale.clone(),
        features: Vec::new(),
        valid: Vec::new(),
        part: None,
        velocities: Default::default(),
    };
    let mut ranges = Vec::with_capacity(clips.len());
    for &i in clips {
        let c = &whole.clips[i];
        let (s, e) = (c.start as usize, c.end as usize);
        let at = db.num_frames as u32;
        let shift = |f: u32| f - c.start + at;
        db.local_positions.extend_from_slice(&whole.local_positions[s * j..e * j]);
        db.local_rotations.extend_from_slice(&whole.local_rotations[s * j..e * j]);
        db.contacts.extend_from_slice(&whole.contacts[2 * s..2 * e]);
        db.features.extend_from_slice(&whole.features[s * d..e * d]);
        db.valid.extend_from_slice(&whole.valid[s..e]);
        for (tag, out) in whole.tags.iter().zip(&mut db.tags) {
            for &(ts, te) in &tag.ranges {
                let (ts, te) = (ts.max(c.start), te.min(c.end));
                if ts < te {
                    out.ranges.push((shift(ts), shift(te)));
                }
            }
        }
        let mut clip = c.clone();
        (clip.start, clip.end) = (at, shift(c.end));
        db.clips.push(clip);
        db.num_frames += e - s;
        ranges.push((c.start, c.end));
    }
    db.part =
        Some(Part { whole: whole_name.to_string(), whole_frames: whole.num_frames as u32, whole_checksum, ranges });
    Ok(db)
}
