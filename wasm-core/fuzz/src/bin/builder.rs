//! Fuzz target: BVH text → parser → builder → `.mmdb` bytes → loader. Whatever the parser
//! accepts, the builder must build or refuse with an error, and what it builds must load.

fn main() {
    afl::fuzz!(|data: &[u8]| {
        mmcore_fuzz::check_build(data);
    });
}
