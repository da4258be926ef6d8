//! Many characters on one database, updated in one call (issue 3: hundreds per frame).

use crate::character::{Character, CharacterSettings};
use crate::controller::Input;
use crate::database::Database;
use crate::limits::{CROWD_MEMORY_BUDGET, CROWD_SEARCH_BUDGET, MAX_CROWD};
use crate::search::SearchIndex;
use glam::{Quat, Vec3};

/// Characters with their own inputs, sharing a database and its search index.
pub struct Crowd {
    pub characters: Vec<Character>,
    pub inputs: Vec<Input>,
}

impl Crowd {
    /// `count` characters on a grid 2 m apart, facing +Z, their locked toes planted at
    /// `toe_floor` (`db`'s [`Database::toe_height_in_contact`], which a caller holding it passes
    /// rather than have it computed again).
    ///
    /// # Errors
    /// More characters than [`Crowd::max_characters`] allows on `db`.
    pub fn new(
        db: &Database,
        count: usize,
        settings: &CharacterSettings,
        toe_floor: Option<f32>,
    ) -> Result<Crowd, String> {
        let most = Crowd::max_characters(db);
        if count > most {
            return Err(format!(
                "crowd: {count} characters asked for; at most {most} on this database ({} frames × {} feature dims: every character searches it at its first update, and a crowd update may compare {} feature values; each character holds ~{} kB of {} MB)",
                db.num_frames,
                db.num_features(),
                CROWD_SEARCH_BUDGET,
                character_bytes(db).div_ceil(1000),
                CROWD_MEMORY_BUDGET >> 20
            ));
        }
        let side = (count as f32).sqrt().ceil().max(1.0) as usize;
        let characters = (0..count)
            .map(|i| {
                let mut c = Character::new(db, settings.clone());
                c.set_toe_floor(toe_floor);
                c.teleport(db, Vec3::new(2.0 * (i % side) as f32, 0.0, 2.0 * (i / side) as f32), Quat::IDENTITY);
                c
            })
            .collect();
        Ok(Crowd { characters, inputs: vec![Input::default(); count] })
    }

    /// The most characters a crowd on `db` may hold, from two budgets (`crate::limits`): every
    /// character searches the whole database at its first update (and whenever its input
    /// changes sharply), so `count × frames × dims` feature values compared in one update stay
    /// within [`CROWD_SEARCH_BUDGET`] (~1 s in WASM); and their memory within
    /// [`CROWD_MEMORY_BUDGET`]. At least 1 and at most [`MAX_CROWD`].
    pub fn max_characters(db: &Database) -> usize {
        let search = (db.num_frames as u64).saturating_mul(db.num_features() as u64).max(1);
        let by_search = CROWD_SEARCH_BUDGET / search;
        let by_memory = CROWD_MEMORY_BUDGET / character_bytes(db) as u64;
        (by_search.min(by_memory) as usize).clamp(1, MAX_CROWD)
    }

    /// Advances every character by `dt` under its input. Allocates nothing.
    pub fn update(&mut self, db: &Database, index: &SearchIndex, dt: f32) {
        for (c, input) in self.characters.iter_mut().zip(&self.inputs) {
            c.update(db, index, input, dt);
        }
    }
}

/// An upper bound of the memory one character of a crowd holds on `db`: the character itself
/// and its per-joint and per-dimension buffers (measured against a counting allocator by
/// `tests/crowd_cost.rs`), and its input.
pub fn character_bytes(db: &Database) -> usize {
    std::mem::size_of::<Character>()
        + std::mem::size_of::<Input>()
        + 1024
        + 256 * db.num_joints()
        + 32 * db.num_features()
}
