//! Helpers shared by the integration tests that read `../shared/mocap` (each test crate uses
//! what it needs).
#![allow(dead_code)]

use mmcore::config::BuildConfig;
use mmcore::{Bvh, Source};
use std::path::{Path, PathBuf};

/// The shared mocap folder beside the repository.
pub fn mocap() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/mocap")
}

/// A parsed BVH under `mocap()`, named by its relative path.
pub fn source(rel: &str) -> Source {
    let path = mocap().join(rel);
    let bytes =
        std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e} (is ../shared beside the repo?)", path.display()));
    Source { name: rel.to_string(), bvh: Bvh::parse(rel, &bytes).unwrap() }
}

pub fn config(json: &str) -> BuildConfig {
    BuildConfig::from_json(json).unwrap()
}
