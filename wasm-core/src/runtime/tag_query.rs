//! Tag queries: which frames a search may return and which it prefers, read off the database's
//! tags (clip tags such as `walk`, motion tags such as `idle`, and styles) — the database tags
//! and cost addends of Unreal's Pose Search, the tag queries of JLPM22's motion matching.
//!
//! A query has three parts (docs/method.md §3, "Tags and styles"):
//! - **require**: a frame must carry every one of these tags;
//! - **exclude**: a frame must carry none of these;
//! - **prefer** + **bias**: a frame that lacks any of these tags costs `bias` more. A style is a
//!   preference: the default `neutral` makes a stylized frame win only where no neutral frame
//!   comes within `bias` of it — "when nothing neutral fits".
//!
//! The first [`MAX_QUERY_TAGS`] tags of a database are queryable: each frame's tags are one
//! `u64` (bit `i` = `db.tags[i]`), so a query is three bit masks and no per-character array
//! (a crowd of a thousand characters shares the bits in the search index). Boxes of frames keep
//! the OR and the AND of their frames' bits, so the pruned search can bound a box's bias and
//! skip a box none of whose frames may be returned, exactly (`search::SearchIndex`).

use crate::database::Database;

/// Tags a query can name: the first 64 of a database (a database has ~15).
pub const MAX_QUERY_TAGS: usize = 64;

/// Prefix of the style tags the builder writes for a clip's `"style"` (`style:angry`); a clip
/// without one is `style:neutral` once any clip of the database has a style.
pub const STYLE_PREFIX: &str = "style:";

/// The style a character prefers unless told otherwise.
pub const NEUTRAL_STYLE: &str = "neutral";

/// Crouch data (docs/database.md "Crouch data"): the builder tags the low-head frames of clips
/// tagged `crouch` with this, and keeps them searchable under `min_head_height`. A character
/// searches them only while its hips are dropped into a crouch ([`crate::character::legs::Legs::crouched`]),
/// and never otherwise, so a standing user never gets a crouched body.
pub const CROUCH_TAG: &str = "crouch";
pub const CROUCHED_TAG: &str = "crouched";

/// A query resolved against one database's tags (bit `i` = `db.tags[i]`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TagQuery {
    pub require: u64,
    pub exclude: u64,
    pub prefer: u64,
    /// Added to the cost of a frame that lacks a preferred tag (≥ 0).
    pub bias: f32,
}

/// The OR (`any`) and AND (`all`) of the tag bits of a run of frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TagSummary {
    pub any: u64,
    pub all: u64,
}

impl TagSummary {
    /// The summary of no frame: the identity of both folds.
    pub const EMPTY: TagSummary = TagSummary { any: 0, all: u64::MAX };

    /// This summary with one more frame's tag bits folded in.
    pub fn with_frame(self, bits: u64) -> TagSummary {
        TagSummary { any: self.any | bits, all: self.all & bits }
    }

    pub fn union(self, other: TagSummary) -> TagSummary {
        TagSummary { any: self.any | other.any, all: self.all & other.all }
    }
}

/// How a query's bias falls on a run of frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RunBias {
    /// No frame of the run is biased.
    None,
    /// Every frame of the run is.
    All(f32),
    /// Some are: look at each frame.
    Mixed,
}

impl TagQuery {
    /// A query that changes nothing: every frame allowed, none biased.
    pub fn is_trivial(&self) -> bool {
        self.require == 0 && self.exclude == 0 && !self.has_bias()
    }

    pub fn has_bias(&self) -> bool {
        self.prefer != 0 && self.bias > 0.0
    }

    /// Whether a frame with tags `bits` may be returned.
    #[inline(always)]
    pub fn allows(&self, bits: u64) -> bool {
        bits & self.require == self.require && bits & self.exclude == 0
    }

    /// The cost added to a frame with tags `bits`.
    #[inline(always)]
    pub fn bias(&self, bits: u64) -> f32 {
        if bits & self.prefer == self.prefer {
            0.0
        } else {
            self.bias
        }
    }

    /// Whether any frame of a run with this summary may be returned (false only when none can).
    #[inline(always)]
    pub fn may_allow(&self, run: TagSummary) -> bool {
        run.any & self.require == self.require && run.all & self.exclude == 0
    }

    /// A lower bound of the bias of every frame of a run: 0 unless no frame can carry every
    /// preferred tag.
    #[inline(always)]
    pub fn min_bias(&self, run: TagSummary) -> f32 {
        if run.any & self.prefer == self.prefer {
            0.0
        } else {
            self.bias
        }
    }

    /// How the bias falls on a run.
    #[inline(always)]
    pub fn run_bias(&self, run: TagSummary) -> RunBias {
        if !self.has_bias() || run.all & self.prefer == self.prefer {
            RunBias::None
        } else if run.any & self.prefer != self.prefer {
            RunBias::All(self.bias)
        } else {
            RunBias::Mixed
        }
    }

    /// Resolves tag names against `db`: names the database lacks (or beyond its first
    /// [`MAX_QUERY_TAGS`] tags) are left out, so a query written for one database plays on
    /// another — a missing required tag must not leave the search with nothing (the TS API
    /// checks names against the database and says which are unknown). `style` is the
    /// preferred style's name (`STYLE_PREFIX` + it is the tag); a database without style
    /// tags prefers nothing. Allocates nothing.
    pub fn resolve<'a>(
        db: &Database,
        require: impl IntoIterator<Item = &'a str>,
        exclude: impl IntoIterator<Item = &'a str>,
        prefer: impl IntoIterator<Item = &'a str>,
        style: &str,
        bias: f32,
    ) -> TagQuery {
        let bits =
            |names: &mut dyn Iterator<Item = &'a str>| names.filter_map(|n| tag_bit(db, n)).fold(0, |a, b| a | b);
        let style_bit = db
            .tags
            .iter()
            .take(MAX_QUERY_TAGS)
            .position(|t| t.name.strip_prefix(STYLE_PREFIX) == Some(style))
            .map_or(0, |i| 1u64 << i);
        TagQuery {
            require: bits(&mut require.into_iter()),
            exclude: bits(&mut exclude.into_iter()),
            prefer: bits(&mut prefer.into_iter()) | style_bit,
            bias: if bias.is_finite() { bias.max(0.0) } else { 0.0 },
        }
    }
}

/// The query bit of tag `name` in `db`, if it is one of its first [`MAX_QUERY_TAGS`] tags.
pub fn tag_bit(db: &Database, name: &str) -> Option<u64> {
    db.tags.iter().take(MAX_QUERY_TAGS).position(|t| t.name == name).map(|i| 1u64 << i)
}

/// Each frame's tag bits (bit `i` = the frame carries `db.tags[i]`), `num_frames` long.
pub fn frame_tag_bits(db: &Database) -> Vec<u64> {
    let mut bits = vec![0u64; db.num_frames];
    for (i, tag) in db.tags.iter().take(MAX_QUERY_TAGS).enumerate() {
        for &(s, e) in &tag.ranges {
            let (s, e) = ((s as usize).min(db.num_frames), (e as usize).min(db.num_frames));
            for b in &mut bits[s..e] {
                *b |= 1 << i;
            }
        }
    }
    bits
}

/// The database's styles (`style:<name>` tags), in tag order.
pub fn styles(db: &Database) -> impl Iterator<Item = &str> {
    db.tags.iter().filter_map(|t| t.name.strip_prefix(STYLE_PREFIX))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_query_allows_and_biases_by_bits() {
        let q = TagQuery { require: 0b001, exclude: 0b100, prefer: 0b010, bias: 2.0 };
        assert!(q.allows(0b011) && q.allows(0b001));
        assert!(!q.allows(0b010) && !q.allows(0b101));
        assert_eq!(q.bias(0b011), 0.0);
        assert_eq!(q.bias(0b001), 2.0);
        // Runs: bounds never exceed any frame's bias, and a run none of whose frames is allowed
        // is recognised.
        let run = TagSummary::EMPTY.with_frame(0b011).with_frame(0b001);
        assert_eq!(q.min_bias(run), 0.0);
        assert_eq!(q.run_bias(run), RunBias::Mixed);
        assert_eq!(q.run_bias(TagSummary::EMPTY.with_frame(0b001)), RunBias::All(2.0));
        assert_eq!(q.run_bias(TagSummary::EMPTY.with_frame(0b011)), RunBias::None);
        assert!(!q.may_allow(TagSummary::EMPTY.with_frame(0b010).with_frame(0b110)));
        assert!(!q.may_allow(TagSummary::EMPTY.with_frame(0b101)));
        assert!(TagQuery::default().is_trivial());
        assert!(TagQuery { prefer: 1, bias: 0.0, ..TagQuery::default() }.is_trivial());
    }
}
