//! When to search and what to search for (docs/method.md §3): every `search_interval` database
//! frames, at once on a sharp input change or a new drive, and at a clip's end. The frame
//! playing is the bar: a jump happens only to something strictly better, outside ±radius.

use super::query::Query;
use super::settings::CharacterSettings;
use crate::database::Database;
use crate::persist::{Persist, Visitor};
use crate::search::{SearchIndex, SearchOptions};

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
    idle: IdleMask,
}

/// The intersection of the user's mask with the database's frames *not* tagged `idle`
/// ([`SearchIndex::not_idle`], made once per database and shared): the frames a search may
/// return while the character is asked to move (`CharacterSettings::idle_exclude_speed`). Its
/// buffer is sized when the mask is set, so an update never allocates.
#[derive(Clone, Debug, Default)]
struct IdleMask {
    combined: Vec<bool>,
    combined_current: bool,
}

/// What a search decided.
pub enum Outcome {
    /// Keep playing.
    Stay,
    /// Jump to this frame.
    Jump(usize),
}

/// The timer and the pending flags; the mask is the caller's setting and the idle mask a cache.
impl Persist for Schedule {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.frames_since_search.persist(v, "frames since search");
        self.force.persist(v, "search forced");
        self.switching.persist(v, "database switch pending");
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

    /// The user's search mask changed: the idle-excluding mask follows.
    pub fn mask_changed(&mut self) {
        self.idle.combined_current = false;
        self.idle.combined.clear();
        if let Some(m) = &self.mask {
            self.idle.combined.reserve_exact(m.len());
        }
    }

    /// Makes the idle-excluding mask current for the database `index` searches.
    pub fn refresh_idle(&mut self, index: &SearchIndex) {
        if !self.idle.combined_current {
            if let (Some(user), Some(not_idle)) = (&self.mask, index.not_idle()) {
                if user.len() == not_idle.len() {
                    self.idle.combined.clear();
                    self.idle.combined.extend(user.iter().zip(not_idle).map(|(a, b)| *a && *b));
                }
            }
            self.idle.combined_current = true;
        }
    }

    /// One database frame was played.
    pub fn count_frame(&mut self) {
        self.frames_since_search += 1;
    }

    /// Searches `index` for `query` (whose pose part must be filled, see [`Query`]) from the
    /// frame playing.
    ///
    /// `moving`: the character is asked to move (faster than `idle_exclude_speed`), so frames
    /// tagged `idle` are not returned (see [`Schedule::refresh_idle`], called before).
    pub fn search(&mut self, index: &SearchIndex, settings: &CharacterSettings, frame: usize, query: &Query, stats: &mut CharacterStats, moving: bool) -> Outcome {
        self.force = false;
        self.frames_since_search = 0;
        let switching = std::mem::take(&mut self.switching);
        let r = settings.exclude_radius;
        let mask = match (moving && !switching, &self.mask, index.not_idle()) {
            (true, Some(_), Some(_)) if self.idle.combined_current && !self.idle.combined.is_empty() => Some(self.idle.combined.as_slice()),
            (true, None, Some(not_idle)) => Some(not_idle),
            (_, user, _) if !switching => user.as_deref(),
            _ => None,
        };
        // A mask made for another database (a character updated with a database it was not
        // switched to) would be read out of range: search unmasked until a new one is set.
        let mask = mask.filter(|m| m.len() == index.num_frames());
        let options = SearchOptions {
            beta_pose: settings.beta_pose,
            beta_trajectory: settings.beta_trajectory,
            exclude: (!switching).then(|| (frame.saturating_sub(r), frame + r + 1)),
            mask,
        };
        // The current frame is the bar: jump only to something strictly better. After a
        // switch every frame is new: no bar.
        let valid_now = !switching && index.is_valid(frame) && mask.is_none_or(|m| m[frame]);
        let bar = if valid_now { index.cost(frame, &query.values, &options) } else { f32::INFINITY };
        let best = index.search(settings.search_method, &query.values, &options, bar);
        stats.searches += 1;
        stats.current_cost = bar;
        match best {
            Some((frame, cost)) => {
                stats.best_cost = cost;
                Outcome::Jump(frame)
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
