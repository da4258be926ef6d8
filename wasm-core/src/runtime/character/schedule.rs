//! When to search and what to search for (docs/method.md §3): every `search_interval` database
//! frames, at once on a sharp input change or a new drive, and at a clip's end. The frame
//! playing is the bar: a jump happens only to something strictly better, outside ±radius.

use super::query::Query;
use super::settings::CharacterSettings;
use crate::database::{Database, Part};
use crate::persist::{Persist, Visitor};
use crate::search::{SearchIndex, SearchOptions};
use crate::tag_query::{tag_bit, TagQuery};

/// Counters and the last search, for debug views and the quality harness.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CharacterStats {
    pub searches: u64,
    pub transitions: u64,
    /// Cost of the current frame at the last search, and of the frame it chose.
    pub current_cost: f32,
    pub best_cost: f32,
    /// Inputs refused (not a number, out of range): the last good value was used instead.
    pub rejected_inputs: u64,
    /// Updates whose `dt` was longer than [`super::MAX_DT`]: a gap searched afresh, not simulated.
    pub gaps: u64,
    /// Times the character found itself in a non-finite state and went back to its last good one.
    pub recoveries: u64,
}

#[derive(Clone, Debug, Default)]
pub struct Schedule {
    frames_since_search: u32,
    /// Search at the next update, whatever the timer says.
    pub force: bool,
    /// Set by a database switch: the next search runs in the new database with the pose
    /// features captured from the old one, and has no bar.
    pub switching: bool,
    /// Frames a search may return (`None`: all valid ones).
    pub mask: Option<Vec<bool>>,
    /// The frame the last jump left (+1; 0: none): searches do not return to within
    /// `exclude_radius` of it. A character dragged at the clamp (the data has no move like the
    /// user's) otherwise traded two standing frames every search — a clip's and its mirror's —
    /// with both feet sliding, for as long as the input lasted.
    left: u32,
}

/// What a search decided.
pub enum Outcome {
    /// Keep playing.
    Stay,
    /// Jump to this frame.
    Jump(usize),
}

/// The timer and the pending flags; the mask is the caller's setting.
impl Persist for Schedule {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.frames_since_search.persist(v, "frames since search");
        self.force.persist(v, "search forced");
        self.switching.persist(v, "database switch pending");
        self.left.persist(v, "frame last left");
    }
}

impl Schedule {
    /// A schedule whose first update searches.
    pub fn new() -> Schedule {
        Schedule { force: true, ..Schedule::default() }
    }

    /// Whether a search is due before playing on from `frame`.
    pub fn is_due(&self, db: &Database, frame: usize, settings: &CharacterSettings) -> bool {
        let at_clip_end = !self.switching && frame + 1 >= db.clips[db.clip_at(frame)].end as usize;
        self.force || self.frames_since_search >= settings.search_interval || at_clip_end
    }

    /// The settings' tag query resolved against `db` (names it lacks are left out), with the
    /// frames tagged `idle` excluded while the character is asked to move (`moving`: faster
    /// than `idle_exclude_speed`) so a walking user is never matched with standing frames.
    /// Resolved per search, by name, so it follows a database switch; allocates nothing.
    /// `crouched`: the character's hips are dropped into a crouch (a tracked user crouching):
    /// the database's crouched frames are then required, else excluded; idle frames are not
    /// excluded while crouched (the crouch data is mostly crouched idle).
    pub fn tag_query(db: &Database, settings: &CharacterSettings, moving: bool, crouched: bool) -> TagQuery {
        let mut query = TagQuery::resolve(
            db,
            settings.require_tags.iter().map(String::as_str),
            settings.exclude_tags.iter().map(String::as_str),
            settings.prefer_tags.iter().map(String::as_str),
            &settings.style,
            settings.style_bias,
        );
        match tag_bit(db, crate::tag_query::CROUCHED_TAG) {
            Some(bit) if crouched => query.require |= bit,
            Some(bit) => query.exclude |= bit,
            None => {}
        }
        if moving && !(crouched && query.require != 0) {
            query.exclude |= tag_bit(db, "idle").unwrap_or(0);
        }
        query
    }

    /// From a first part to its whole ([`super::Character::enter_whole`]): the frame last left
    /// becomes the same frame of the whole; the part's mask is lifted.
    pub fn enter_whole(&mut self, part: &Part) {
        if self.left > 0 {
            self.left = part.whole_frame(self.left as usize - 1).map_or(0, |f| f as u32 + 1);
        }
        self.mask = None;
    }

    /// Whether the frame the last jump left is one of `num_frames` (a loaded state's check).
    pub fn left_is_within(&self, num_frames: usize) -> bool {
        self.left as usize <= num_frames
    }

    /// One database frame was played.
    pub fn count_frame(&mut self) {
        self.frames_since_search += 1;
    }

    /// Searches `index` for `query` (whose pose part must be filled, see [`Query`]) from the
    /// frame playing, among the frames `tags` allows ([`Schedule::tag_query`]).
    pub fn search(
        &mut self,
        index: &SearchIndex,
        settings: &CharacterSettings,
        frame: usize,
        query: &Query,
        stats: &mut CharacterStats,
        tags: TagQuery,
    ) -> Outcome {
        self.force = false;
        self.frames_since_search = 0;
        let switching = std::mem::take(&mut self.switching);
        let r = settings.exclude_radius;
        // The user's mask belongs to the database it was made for: not across a switch.
        let mask = if switching { None } else { self.mask.as_deref() };
        // A mask made for another database (a character updated with a database it was not
        // switched to) would be read out of range: search unmasked until a new one is set.
        let mask = mask.filter(|m| m.len() == index.num_frames());
        let options = SearchOptions {
            beta_pose: settings.beta_pose,
            beta_trajectory: settings.beta_trajectory,
            exclude: (!switching).then(|| (frame.saturating_sub(r), frame + r + 1)),
            exclude_recent: (!switching && self.left > 0).then(|| {
                let left = self.left as usize - 1;
                (left.saturating_sub(r), left.saturating_add(r).saturating_add(1))
            }),
            mask,
            tags,
        };
        // The current frame is the bar: jump only to something strictly better. After a
        // switch every frame is new: no bar.
        let valid_now =
            !switching && index.is_valid(frame) && mask.is_none_or(|m| m[frame]) && index.tags_allow(frame, &tags);
        let bar = if valid_now { index.cost(frame, &query.values, &options) } else { f32::INFINITY };
        let best = index.search(settings.search_method, &query.values, &options, bar);
        stats.searches += 1;
        stats.current_cost = bar;
        match best {
            Some((best, cost)) => {
                stats.best_cost = cost;
                self.left = if switching { 0 } else { frame as u32 + 1 };
                Outcome::Jump(best)
            }
            // Nothing searchable in the new database: cut to its first frame.
            None if switching => Outcome::Jump(0),
            // The frame playing is the best there is.
            None => {
                stats.best_cost = bar;
                Outcome::Stay
            }
        }
    }
}
