//! Motion matching core: BVH and glTF animation import, motion database build, the `.mmdb` format, search and
//! the runtime (springs, trajectory, inertialization, IK).
//! The pure core never touches wasm-bindgen; `bindings/` is the only JS-facing module, one
//! file per `Raw*` class, mirrored file for file by the TypeScript raw layer (`web/src/core/`).

// The runtime (what a page runs every frame) apart from the offline part (import, database
// build, the CLI's tools) and the harnesses that measure the runtime, as ozz-animation keeps
// `runtime/` and `offline/`: no runtime module imports an offline one or a harness
// (tests/unit/structure.test.ts). The modules are re-exported at the crate root, so every path
// (`mmcore::search`, `crate::builder`) names the module, not the folder.
pub mod harness;
pub mod offline;
pub mod runtime;

pub mod error;
pub mod format;
pub mod limits;
pub mod rng;

pub use harness::{naturalness, quality, vr_replay};
pub use offline::{builder, bvh, config, first_part, frame_cuts, gltf, inspect, parallel, smoothing};
pub use runtime::{
    aabb, character, closed_mesh, controller, crowd, database, ik, inertialize, kinematics, lanes, mirror, persist,
    pose_features, recording, retarget, roles, search, skating, skinning, spring, tag_query,
};

#[cfg(target_arch = "wasm32")]
mod bindings;

pub use builder::{build, BuildOutput, Source};
pub use bvh::Bvh;
pub use config::BuildConfig;
pub use database::Database;
pub use error::{Error, Result};
