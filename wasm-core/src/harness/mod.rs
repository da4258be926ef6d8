//! Harnesses: scripted runs that measure the runtime (the quality harness, the naturalness
//! check, native VR replays). They drive the runtime from outside; the runtime never uses them.

pub mod naturalness;
pub mod quality;
pub mod vr_replay;
