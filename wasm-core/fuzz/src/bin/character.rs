//! Fuzz target: the character update under any sequence of calls with any values (see
//! `mmcore_fuzz::check_character`).

fn main() {
    afl::fuzz!(|data: &[u8]| {
        mmcore_fuzz::check_character(data);
    });
}
