"""The runtime's crouch rule (`wasm-core/src/runtime/character/crouch.rs`) against the mocap's truth:
its constants are the ones fitted on the training subjects, and on the held-out subjects it
predicts the hips drop and the torso bend far better than letting the hips take the whole drop."""

import numpy as np
import pytest

from orientation import crouch_fit


@pytest.fixture(scope="module")
def frames():
    return crouch_fit.load_frames(log=lambda *_: None)


def test_the_runtime_uses_the_fitted_constants(frames):
    c = crouch_fit.rust_constants()
    start, gain = crouch_fit.fit(frames, deadband=c["CROUCH_DEADBAND"], max_bend=c["MAX_BEND"])
    assert np.isclose(start, c["BEND_START_PITCH"], atol=1e-6) and gain == c["BEND_GAIN"], (
        f"the training subjects fit {np.degrees(start):.0f}° and {gain}; crouch.rs has {np.degrees(c['BEND_START_PITCH']):.0f}° and {c['BEND_GAIN']}"
    )


def test_held_out_people_bending_over_are_not_crouched(frames):
    c = crouch_fit.rust_constants()
    base = dict(deadband=c["CROUCH_DEADBAND"], max_bend=c["MAX_BEND"])
    before = crouch_fit.score(frames, start_pitch=0.0, gain=0.0, bend=False, **base)
    rule = crouch_fit.score(frames, start_pitch=c["BEND_START_PITCH"], gain=c["BEND_GAIN"], **base)
    assert rule["held_out_hips_low"] < 0.5 * before["held_out_hips_low"], (rule, before)
    assert rule["held_out_bend_low"] < 0.5 * before["held_out_bend_low"], (rule, before)
    assert rule["held_out_bend"] < before["held_out_bend"]
    # A walk's head bob never bends the torso.
    assert rule["upright_bend_p95"] == 0.0
    # CMU 14 (bending over laughing, mopping) is where it matters.
    m = (frames.subject == "cmu-asf_14") & (frames.head_drop > 0.05)
    assert m.sum() > 1000
    hips, _ = crouch_fit.split(
        frames.head_drop[m], frames.pitch[m], frames.torso[m], c["BEND_START_PITCH"], c["BEND_GAIN"], **base
    )
    assert np.abs(hips - frames.hips_drop[m]).mean() < 0.04
