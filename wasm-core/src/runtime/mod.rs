//! The runtime: what a page runs every frame — the database it reads, the search, the character
//! (springs, inertialization, foot lock, IK), crowds and retargeting — and nothing of the
//! import, the database build or the harnesses (`crate::offline`, `crate::harness`).

pub mod aabb;
pub mod character;
pub mod closed_mesh;
pub mod controller;
pub mod crowd;
pub mod database;
pub mod ik;
pub mod inertialize;
pub mod kinematics;
pub mod lanes;
pub mod mirror;
pub mod persist;
pub mod pose_features;
pub mod recording;
pub mod retarget;
pub mod roles;
pub mod search;
pub mod skating;
pub mod skinning;
pub mod spring;
pub mod tag_query;
