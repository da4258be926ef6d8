//! `validate_recording`: the page's recording validator is the CLI's (`recording::validate`), so
//! `mmdb replay` accepts exactly the recordings the VR page replays.

use crate::recording;
use wasm_bindgen::prelude::*;

/// Checks a decoded recording's values (`web/src/vr/recording.ts` passes its arrays); throws the
/// first thing wrong. `has_truth` says whether `truth_yaw` and `truth_root` are given.
#[wasm_bindgen]
#[allow(clippy::too_many_arguments)]
pub fn validate_recording(
    frames: f64,
    time: &[f64],
    position: &[f64],
    rotation: &[f64],
    tracked: &[u8],
    has_truth: bool,
    truth_yaw: &[f64],
    truth_root: &[f64],
) -> Result<(), JsError> {
    recording::validate(frames, time, position, rotation, tracked, has_truth.then_some((truth_yaw, truth_root)))
        .map_err(|e| JsError::new(&e))
}
