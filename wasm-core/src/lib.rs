//! Motion matching core: BVH and glTF animation import, motion database build, the `.mmdb` format, search and
//! the runtime (springs, trajectory, inertialization, IK).
//! The pure core never touches wasm-bindgen; `bindings/` is the only JS-facing module, one
//! file per `Raw*` class, mirrored file for file by the TypeScript raw layer (`web/src/core/`).

pub mod aabb;
pub mod builder;
pub mod bvh;
pub mod character;
pub mod config;
pub mod controller;
pub mod crowd;
pub mod database;
pub mod error;
pub mod format;
pub mod frame_cuts;
pub mod gltf;
pub mod ik;
pub mod inertialize;
pub mod inspect;
pub mod kinematics;
pub mod limits;
pub mod naturalness;
pub mod lanes;
pub mod parallel;
pub mod persist;
pub mod quality;
pub mod retarget;
pub mod rng;
pub mod roles;
pub mod search;
pub mod skating;
pub mod smoothing;
pub mod spring;
pub mod tag_query;
pub mod vr_replay;

#[cfg(target_arch = "wasm32")]
mod bindings;

pub use builder::{build, BuildOutput, Source};
pub use bvh::Bvh;
pub use config::BuildConfig;
pub use database::Database;
pub use error::{Error, Result};
