//! `RawCrowd`: many characters on a shared database, updated in one call (hundreds per frame).

use super::database::{RawDatabase, Shared};
use super::{Kind, LiveToken};
use crate::character::CharacterSettings;
use crate::controller::Input;
use crate::crowd::Crowd;
use glam::Vec2;
use std::rc::Rc;
use wasm_bindgen::prelude::*;

#[wasm_bindgen]
pub struct RawCrowd {
    shared: Rc<Shared>,
    crowd: Crowd,
    _live: LiveToken,
}

#[wasm_bindgen]
impl RawCrowd {
    /// `count` characters on a 2 m grid on `database` (shared, not copied).
    ///
    /// # Errors
    /// More characters than [`Crowd::max_characters`] allows on the database.
    #[wasm_bindgen(constructor)]
    pub fn new(database: &RawDatabase, count: usize) -> Result<RawCrowd, JsError> {
        let shared = Rc::clone(&database.shared);
        let crowd = Crowd::new(&shared.db, count, &CharacterSettings::default(), shared.toe_floor)
            .map_err(|e| JsError::new(&e))?;
        Ok(RawCrowd { shared, crowd, _live: LiveToken::new(Kind::Crowd) })
    }

    /// The most characters a crowd on `database` may hold (see `Crowd::max_characters`).
    pub fn max_characters(database: &RawDatabase) -> usize {
        Crowd::max_characters(&database.shared.db)
    }

    /// Input of character `i` (see `RawCharacter.set_input`); out-of-range `i` is ignored.
    #[allow(clippy::too_many_arguments)]
    pub fn set_input(&mut self, i: usize, move_x: f32, move_z: f32, face_x: f32, face_z: f32, run: bool, strafe: bool) {
        if let Some(input) = self.crowd.inputs.get_mut(i) {
            *input = Input { direction: Vec2::new(move_x, move_z), facing: Vec2::new(face_x, face_z), run, strafe };
        }
    }

    /// Advances every character by `dt` seconds.
    pub fn update(&mut self, dt: f32) {
        let s = &*self.shared;
        self.crowd.update(&s.db, &s.index, dt);
    }

    /// `J×3` f32 world positions of character `i`'s shown pose (clamped to the last character).
    pub fn world_positions_ptr(&self, i: usize) -> *const f32 {
        let i = i.min(self.crowd.characters.len().saturating_sub(1));
        self.crowd.characters.get(i).map_or(std::ptr::null(), |c| c.world_positions().as_ptr().cast())
    }
}
