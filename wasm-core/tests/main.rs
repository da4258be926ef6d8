//! Every integration test in one binary (`autotests = false` in Cargo.toml): one link instead
//! of one per file — on 2 cores each test binary was a separate optimized link of the whole
//! crate — and one process whose test threads keep both cores busy. Each file below is still
//! one concern; `cargo test --test integration <file>::` runs one of them.

mod common;
mod hostile;

/// One counting allocator for all of them: per-thread heap and allocation counts
/// (`hostile::alloc`), so a test measures only its own work while others run beside it.
#[global_allocator]
static ALLOCATOR: hostile::alloc::Counting = hostile::alloc::Counting;

mod build_limits;
mod cli;
mod crowd_cost;
mod databases;
mod gltf;
mod hostile_bvh;
mod hostile_character;
mod hostile_cli;
mod hostile_mmdb;
mod import;
mod mocap;
mod retarget;
mod roundtrip;
mod runtime;
mod runtime_math;
mod search;
mod soak;
