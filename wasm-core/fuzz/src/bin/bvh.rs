//! Fuzz target: the BVH parser. Any input must give `Ok` with a consistent `Bvh` or a short
//! error naming the file and a line — never a panic (AFL reports panics and aborts as crashes).

fn main() {
    afl::fuzz!(|data: &[u8]| {
        mmcore_fuzz::check_bvh(data);
    });
}
