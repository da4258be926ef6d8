//! `validate_recording`: the page's recording validator is the CLI's (`recording::validate`), so
//! `mmdb replay` accepts exactly the recordings the VR page replays.

use crate::recording;
use wasm_bindgen::prelude::*;

/// Checks a decoded recording's values (`web/src/vr/recording.ts` passes its arrays); throws the
/// first thing wrong. `has_truth` says whether `truth_yaw` and `truth_root` are given;
/// `body_joints` > 0 that the body joints' arrays are (`recording::validate_body`).
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
    body_joints: usize,
    body_position: &[f64],
    body_rotation: &[f64],
    body_tracked: &[u8],
) -> Result<(), JsError> {
    recording::validate(frames, time, position, rotation, tracked, has_truth.then_some((truth_yaw, truth_root)))
        .and_then(|()| match body_joints {
            0 => Ok(()),
            j => recording::validate_body(frames, j, body_position, body_rotation, body_tracked),
        })
        .map_err(|e| JsError::new(&e))
}
