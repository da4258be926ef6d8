//! Time reversal (an augmentation, off by default): a take played backward. Walking forward
//! played backward is a plausible back-step — the same feet, the same contacts, the root moving
//! against its facing — where capture of sustained backward walking is scarce. Velocities,
//! contacts and features are recomputed on the reversed frames like on any clip (the contact
//! test is on toe speed, which reversal keeps). What it cannot fake: a real back-step loads the
//! feet differently (toe first, shorter steps); `docs/database.md` measures whether it helps.

use super::poses::Poses;

/// `out` = `poses` with the frames in reverse order.
pub fn reverse(poses: &Poses, out: &mut Poses) {
    let (n, j) = (poses.num_frames(), poses.num_joints);
    out.reset(j, n);
    for f in (0..n).rev() {
        for k in 0..j {
            let (t, q) = poses.at(f, k);
            out.push(t, q);
        }
    }
}
