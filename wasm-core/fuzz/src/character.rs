//! The character-update property, one function for the AFL target (`fuzz/src/bin/character.rs`)
//! and the native test that replays it on every `cargo test` (`tests/hostile_character.rs`):
//! any sequence of calls with any values — NaN, ±∞, 1e38, negative `dt`, garbage paths, masks
//! and settings — leaves a character whose pose and root are finite, whose frame is in the
//! database, and whose root stays within `clamp_distance` of its simulated twin after an update.
//! Needs only `mmcore`, so both crates compile it.

use glam::{Quat, Vec2, Vec3};
use mmcore::character::{Character, CharacterSettings, Tracked};
use mmcore::controller::{Input, Path};
use mmcore::search::SearchIndex;
use mmcore::{format, Database};
use std::sync::OnceLock;

/// A small humanoid database (the builder's output for a synthetic walk, committed as a seed).
fn database() -> &'static (Database, SearchIndex) {
    static DB: OnceLock<(Database, SearchIndex)> = OnceLock::new();
    DB.get_or_init(|| {
        let db = format::from_bytes(include_bytes!("../../tests/corpus/mmdb/humanoid.mmdb"))
            .expect("the committed humanoid.mmdb loads");
        let index = SearchIndex::new(&db).expect("its index");
        (db, index)
    })
}

/// Reads values from the fuzzer's bytes; past the end everything is zero.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn byte(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }
    /// Any bit pattern: NaN, ±∞, subnormals and 1e38 all come out.
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes([self.byte(), self.byte(), self.byte(), self.byte()])
    }
    fn vec2(&mut self) -> Vec2 {
        Vec2::new(self.f32(), self.f32())
    }
    fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.f32(), self.f32(), self.f32())
    }
}

/// Settings a page may patch at run time (any value: the patch is refused or applied whole).
const SETTINGS: [&str; 8] = [
    "clamp_distance",
    "playback_speed",
    "search_interval",
    "inertialization_halflife",
    "clamp_angle",
    "adjustment_max_ratio",
    "foot_lock_unlock_radius",
    "exclude_radius",
];

/// Runs the calls `data` encodes (at most 256) on a fresh character; panics if a property breaks.
pub fn check_character(data: &[u8]) {
    let (db, index) = database();
    let mut c = Character::new(db, CharacterSettings::default());
    c.set_toe_floor(db.toe_height_in_contact());
    let mut r = Reader(data);
    let mut input = Input::default();
    for _ in 0..256 {
        if r.0.is_empty() {
            break;
        }
        let updated = match r.byte() % 11 {
            0 => {
                let flags = r.byte();
                input = Input { direction: r.vec2(), facing: r.vec2(), run: flags & 1 != 0, strafe: flags & 2 != 0 };
                c.update(db, index, &input, r.f32());
                true
            }
            1 => {
                c.set_tracked(Tracked { position: r.vec3(), velocity: r.vec3(), yaw: r.f32(), body: r.f32() > 0.0 });
                false
            }
            2 => {
                let p = r.vec3();
                c.teleport(db, p, Quat::from_xyzw(r.f32(), r.f32(), r.f32(), r.f32()));
                false
            }
            3 => {
                // The crouch: a hips drop, a torso bend, or a head drop and pitch to split.
                let (a, b) = (r.f32(), r.f32());
                match r.byte() % 3 {
                    0 => c.set_hips_drop(a),
                    1 => c.set_torso_bend(a),
                    _ => {
                        let _ = c.set_crouch(a, b);
                    }
                }
                false
            }
            4 => {
                let n = (r.byte() % 9) as usize;
                let points: Vec<Vec3> = (0..n).map(|_| r.vec3()).collect();
                let speeds: Vec<f32> = (0..(r.byte() % 3) as usize).map(|_| r.f32()).collect();
                if let Ok(path) = Path::new(&points, &speeds, r.byte() & 1 != 0) {
                    c.set_path(Some(path));
                }
                false
            }
            5 => {
                c.set_path(None);
                false
            }
            6 => {
                let key = SETTINGS[(r.byte() as usize) % SETTINGS.len()];
                let value = r.f32();
                // A NaN or ∞ prints as non-JSON: that patch is refused like any other bad one.
                if let Ok(s) = c.settings.patched(&format!("{{\"{key}\": {value}}}")) {
                    c.settings = s;
                }
                false
            }
            7 => {
                let (len, bits) = (db.num_frames + (r.byte() % 3) as usize - 1, r.byte());
                let mask =
                    (bits & 1 != 0).then(|| (0..len).map(|f| (f as u8).wrapping_mul(bits) & 0x80 != 0).collect());
                let _ = c.set_mask(db, mask);
                false
            }
            8 => {
                c.request_search();
                false
            }
            9 => {
                // The runtime state through the network: saved, up to 7 bytes damaged, loaded
                // (refused whole, or loaded and then held to the same properties).
                let mut state = c.save_state(db);
                for _ in 0..r.byte() % 8 {
                    let at = (r.byte() as usize) << 8 | r.byte() as usize;
                    let len = state.len();
                    state[at % len] ^= r.byte();
                }
                let _ = c.load_state(db, &state);
                false
            }
            _ => {
                // A burst of ordinary frames, so states reached by bad calls get played on.
                let n = r.byte() % 64;
                for _ in 0..n {
                    c.update(db, index, &input, 1.0 / 60.0);
                }
                n > 0
            }
        };
        assert!(c.world_positions().iter().all(|p| p.is_finite()), "non-finite pose");
        assert!(c.world_rotations().iter().all(|q| q.is_finite()), "non-finite rotation");
        assert!(c.root_position().is_finite() && c.root_rotation().is_finite(), "non-finite root");
        assert!(c.frame() < db.num_frames, "frame {} of {}", c.frame(), db.num_frames);
        if updated {
            let (sim, _) = c.simulation_transform();
            let gap = Vec2::new(c.root_position().x - sim.x, c.root_position().z - sim.z).length();
            // Within α up to f32 rounding where the character stands: 61 km from the origin
            // (teleports go to 100 km) a coordinate's step is 4 mm, and AFL found a clamp there
            // 1.1 mm past α; two steps of the larger coordinate bound that rounding.
            let far = c.root_position().abs().max_element().max(sim.abs().max_element());
            let rounding = 2.0 * far * f32::EPSILON;
            assert!(
                gap <= c.settings.clamp_distance + 1e-3 + rounding,
                "root {gap} m from the simulation (α {})",
                c.settings.clamp_distance
            );
        }
    }
}
