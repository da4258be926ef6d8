//! Crowds sized by cost and characters that allocate nothing from their first update (issue
//! 28): `new Crowd(db, 100000)` was accepted and its first update took 304 s, and each
//! character's first update allocated one byte per database frame (its idle mask).

use crate::common;
use crate::hostile;

use glam::Vec2;
use hostile::alloc;
use mmcore::character::{Character, CharacterSettings};
use mmcore::config::BuildConfig;
use mmcore::controller::Input;
use mmcore::crowd::{character_bytes, Crowd};
use mmcore::limits::{CROWD_MEMORY_BUDGET, CROWD_SEARCH_BUDGET, MAX_CROWD};
use mmcore::search::SearchIndex;
use mmcore::{build, Bvh, Database, Source};

/// A walk whose first 100 source frames are tagged `idle`, so characters have an idle mask.
fn database(json: &str) -> Database {
    let source =
        Source { name: "walk.bvh".into(), bvh: Bvh::parse("walk.bvh", hostile::humanoid_bvh(400).as_bytes()).unwrap() };
    build(&BuildConfig::from_json(json).unwrap(), &[source]).unwrap().database
}

const IDLE: &str = r#"{"clips": [{"file": "walk.bvh", "ranges": [{"frames": [0, 100], "tags": ["idle"]}]}]}"#;

#[test]
fn a_character_allocates_nothing_from_its_first_update() {
    let db = database(IDLE);
    // Its velocities are derived a block at a time when first played (the database's, shared by
    // every character, once): all of them now, so what is counted is the characters' own.
    db.derive_velocities();
    assert!(db.tag_mask("idle").is_some());
    let index = SearchIndex::new(&db).unwrap();
    assert!(mmcore::tag_query::tag_bit(&db, "idle").is_some(), "the idle exclusion is a tag query");
    let walk = Input { direction: Vec2::new(0.0, 1.0), ..Input::default() };
    let mut c = Character::new(&db, CharacterSettings::default());
    let ((), bytes) = alloc::measure(|| c.update(&db, &index, &walk, 1.0 / 60.0));
    assert_eq!(bytes, 0, "the first update allocated {bytes} B");
    // With a search mask set: the buffer it is combined into is sized when it is set.
    let mask: Vec<bool> = (0..db.num_frames).map(|f| f % 3 != 0).collect();
    c.set_mask(&db, Some(mask)).unwrap();
    let ((), bytes) = alloc::measure(|| {
        for _ in 0..30 {
            c.update(&db, &index, &walk, 1.0 / 60.0);
        }
    });
    assert_eq!(bytes, 0, "updates after a new mask allocated {bytes} B");
    assert!(c.stats.searches >= 2);
    // A crowd's first update, every character searching.
    let mut crowd = Crowd::new(&db, 50, &CharacterSettings::default(), db.toe_height_in_contact()).unwrap();
    crowd.inputs.iter_mut().for_each(|i| *i = walk);
    let ((), bytes) = alloc::measure(|| crowd.update(&db, &index, 1.0 / 60.0));
    assert_eq!(bytes, 0, "a crowd's first update allocated {bytes} B");
}

/// A crowd's size comes from two budgets: the feature values its first update compares
/// (`count × frames × dims`) and the memory its characters hold; past either it is an error
/// that says how many fit. One character is always allowed.
#[test]
fn a_crowd_is_sized_by_its_first_update_and_its_memory() {
    let db = database("{}");
    let most = Crowd::max_characters(&db);
    let per_search = (db.num_frames * db.num_features()) as u64;
    assert_eq!(
        most as u64,
        (CROWD_SEARCH_BUDGET / per_search).min(CROWD_MEMORY_BUDGET / character_bytes(&db) as u64).min(MAX_CROWD as u64)
    );
    assert!(
        most as u64 * per_search <= CROWD_SEARCH_BUDGET
            && most as u64 * character_bytes(&db) as u64 <= CROWD_MEMORY_BUDGET
    );
    let e = Crowd::new(&db, 100_000, &CharacterSettings::default(), None).err().unwrap();
    assert!(
        e.starts_with(&format!(
            "crowd: 100000 characters asked for; at most {most} on this database ({} frames × {} feature dims",
            db.num_frames,
            db.num_features()
        )),
        "{e}"
    );
    assert!(Crowd::new(&db, most + 1, &CharacterSettings::default(), None).is_err());
    // The locomotion database's size (24,688 frames × 27 dims): 6,443 characters, ~1 s of search.
    assert_eq!(CROWD_SEARCH_BUDGET / (24_688 * 27), 6443);
    // The largest database the loader accepts (2²⁴ frames × 128 dims): 2 characters. However
    // large, at least one.
    let mut huge = db.clone();
    huge.num_frames = 1 << 24;
    huge.feature_mean.resize(128, 0.0);
    assert_eq!(Crowd::max_characters(&huge), 2);
    huge.num_frames = usize::MAX;
    assert_eq!(Crowd::max_characters(&huge), 1);
    // The largest crowd builds and its first update searches for every character.
    let index = SearchIndex::new(&db).unwrap();
    let n = most.min(2_000);
    let mut crowd = Crowd::new(&db, n, &CharacterSettings::default(), db.toe_height_in_contact()).unwrap();
    crowd.update(&db, &index, 1.0 / 60.0);
    assert!(crowd.characters.iter().all(|c| c.stats.searches == 1));
}

/// `character_bytes` bounds what a character holds (on databases of 15 and 32 joints, 27
/// and 106 feature dims): the memory budget counts on it.
#[test]
fn a_character_holds_less_than_character_bytes() {
    let wide = r#"{"features": [{"name": "t", "kind": "position", "joint": "root", "offsets": [1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18,19,20,21,22,23,24,25,26,27,28,29,30,31,32]},
                                {"name": "f", "kind": "velocity", "joint": "left_foot", "offsets": [0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18,19,20]}]}"#;
    let cmu = build(&BuildConfig::default(), &[common::source("cmu-asf/cmu_02_06.bvh")]).unwrap().database;
    for db in [database("{}"), database(wide), cmu] {
        db.derive_velocities(); // the database's, not the character's (see above)
        let (c, bytes) = alloc::measure(|| Character::new(&db, CharacterSettings::default()));
        let bound = character_bytes(&db) - std::mem::size_of::<Character>() - std::mem::size_of::<Input>();
        eprintln!(
            "{} joints, {} dims: a character holds {bytes} B on the heap (bound {bound} B)",
            db.num_joints(),
            db.num_features()
        );
        assert!(bytes <= bound, "{bytes} B > {bound} B");
        drop(c);
    }
}
