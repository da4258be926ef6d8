//! Many characters on one database, updated in one call (issue 3: hundreds per frame).

use crate::character::{Character, CharacterSettings};
use crate::controller::Input;
use crate::database::Database;
use crate::search::SearchIndex;
use glam::{Quat, Vec3};

/// Characters with their own inputs, sharing a database and its search index.
pub struct Crowd {
    pub characters: Vec<Character>,
    pub inputs: Vec<Input>,
}

impl Crowd {
    /// `count` characters on a grid 2 m apart, facing +Z.
    pub fn new(db: &Database, count: usize, settings: &CharacterSettings) -> Crowd {
        let side = (count as f32).sqrt().ceil().max(1.0) as usize;
        let floor = db.toe_height_in_contact();
        let characters = (0..count)
            .map(|i| {
                let mut c = Character::new(db, settings.clone());
                c.set_toe_floor(floor);
                c.teleport(db, Vec3::new(2.0 * (i % side) as f32, 0.0, 2.0 * (i / side) as f32), Quat::IDENTITY);
                c
            })
            .collect();
        Crowd { characters, inputs: vec![Input::default(); count] }
    }

    /// Advances every character by `dt` under its input. Allocates nothing.
    pub fn update(&mut self, db: &Database, index: &SearchIndex, dt: f32) {
        for (c, input) in self.characters.iter_mut().zip(&self.inputs) {
            c.update(db, index, input, dt);
        }
    }
}
