//! Foot contacts (docs/method.md §1): a toe is in contact while its speed is under a threshold,
//! then a median filter (a majority vote over 2r+1 frames) removes flicker.

/// Writes `2 × num_frames` contact flags (left, right) into `out`. `toe_speed(side, f)` is the
/// toe's speed (m/s) or `None` without a toe; `raw` is scratch.
pub fn contacts(
    num_frames: usize,
    toe_speed: impl Fn(usize, usize) -> Option<f64>,
    threshold: f64,
    radius: usize,
    raw: &mut Vec<[bool; 2]>,
    out: &mut [u8],
) {
    raw.clear();
    raw.resize(num_frames, [false; 2]);
    for side in 0..2 {
        for (f, r) in raw.iter_mut().enumerate() {
            r[side] = toe_speed(side, f).is_some_and(|s| s < threshold);
        }
    }
    for f in 0..num_frames {
        let (a, b) = (f.saturating_sub(radius), (f + radius).min(num_frames - 1));
        for side in 0..2 {
            let on = (a..=b).filter(|&g| raw[g][side]).count();
            out[2 * f + side] = (2 * on > b - a + 1) as u8;
        }
    }
}
