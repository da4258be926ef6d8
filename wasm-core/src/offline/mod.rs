//! Offline: BVH and glTF import, the database build and its config, and the tools the CLI uses
//! to look inside a database. May use the runtime (the builder retargets and solves IK with it);
//! the runtime never uses this.

pub mod builder;
pub mod bvh;
pub mod config;
pub mod first_part;
pub mod frame_cuts;
pub mod gltf;
pub mod inspect;
pub mod parallel;
pub mod smoothing;
