//! Fuzz target: the `.mmdb` loader, each input loaded as it is and with its size and CRC
//! rewritten (see `mmcore_fuzz::check_mmdb`).

fn main() {
    afl::fuzz!(|data: &[u8]| {
        mmcore_fuzz::check_mmdb(data);
    });
}
