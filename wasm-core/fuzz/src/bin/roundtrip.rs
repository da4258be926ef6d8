//! Fuzz target: bytes → a build configuration and BVH takes → build → write → load → a
//! character plays (`fuzz/src/roundtrip.rs`): whatever `build` accepts must load and play.

fn main() {
    afl::fuzz!(|data: &[u8]| {
        mmcore_fuzz::roundtrip::check_round_trip(data);
    });
}
