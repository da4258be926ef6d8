//! The properties the fuzz targets check, as plain functions. Inputs AFL finds crashing are
//! fixed, then kept in `fuzz/regressions/<target>/`, which the native tests
//! (`tests/hostile_*.rs`) replay on every `cargo test`.

pub mod character;
pub mod roundtrip;
pub use character::check_character;

use mmcore::limits::{MAX_FPS, MAX_JOINTS, MAX_MESSAGE_CHARS, MIN_FPS};
use mmcore::{format, Bvh};

/// Parses `data` as BVH; panics if the outcome breaks a documented property.
pub fn check_bvh(data: &[u8]) -> Option<Bvh> {
    match Bvh::parse("fuzz.bvh", data) {
        Ok(bvh) => {
            assert_eq!(bvh.values.len(), bvh.num_frames * bvh.num_channels);
            assert!(bvh.joints.len() <= MAX_JOINTS);
            assert!(bvh.values.iter().all(|v| v.is_finite()));
            Some(bvh)
        }
        Err(e) => {
            let m = e.to_string();
            assert!(m.starts_with("fuzz.bvh:"), "{m}");
            assert!(m.chars().count() <= MAX_MESSAGE_CHARS + 40, "message of {} chars", m.chars().count());
            None
        }
    }
}

/// Loads `data` as `.mmdb` twice: as it is, and with the size and CRC rewritten (so that
/// mutations reach the section parsers instead of all failing the checksum). A database that
/// loads must be within the limits and survive a summary, a search and a round trip (within
/// the quantization bound).
pub fn check_mmdb(data: &[u8]) {
    load(data);
    if data.len() >= 32 {
        let mut bytes = data.to_vec();
        let n = bytes.len() as u64;
        bytes[16..24].copy_from_slice(&n.to_le_bytes());
        let crc = crc32fast::hash(&bytes[32..]);
        bytes[24..28].copy_from_slice(&crc.to_le_bytes());
        load(&bytes);
    }
}

fn load(bytes: &[u8]) {
    match format::from_bytes(bytes) {
        Ok(db) => {
            assert!((MIN_FPS as f32..=MAX_FPS as f32).contains(&db.fps));
            assert!(db.num_frames >= 1 && db.num_features() >= 1);
            let _ = mmcore::inspect::summary(&db, Some(bytes.len()));
            let index = mmcore::search::SearchIndex::new(&db).expect("index of a loaded database");
            index.search(mmcore::search::SearchMethod::Aabb, db.feature(0), &Default::default(), f32::INFINITY);
            match format::from_bytes(&format::to_bytes(&db)) {
                Ok(again) => format::check_round_trip(&db, &again).unwrap(),
                // A version-1/2 file's stored features need not be what its poses give; written
                // as version 3 (derived) they may be out of bounds, a clear error.
                Err(e) => {
                    assert!(e.to_string().contains("features derived") && db.derived_features() != db.features, "{e}")
                }
            }
        }
        Err(e) => assert!(e.to_string().chars().count() <= MAX_MESSAGE_CHARS + 20),
    }
}

/// Parses, builds (no mirror, 30 fps to keep runs short) and reloads.
pub fn check_build(data: &[u8]) {
    let Some(bvh) = check_bvh(data) else { return };
    let config = mmcore::BuildConfig { fps: 30.0, mirror: false, ..Default::default() };
    let source = mmcore::Source { name: "fuzz.bvh".into(), bvh };
    if let Ok(out) = mmcore::build(&config, &[source]) {
        let bytes = format::to_bytes(&out.database);
        if let Err(e) = format::from_bytes(&bytes) {
            panic!("the builder wrote a database its loader refuses: {e}");
        }
    }
}
