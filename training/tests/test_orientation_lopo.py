"""Leave-one-person-out (`orientation.lopo`): the stacked folds are independent networks, a fold
never sees its person, and the reduced run CI does scores every held-out person by class."""

import numpy as np
import pytest
import torch

from orientation import data, lopo
from orientation.features import FRAME_INPUTS, NUM_INPUTS
from orientation.motion_classes import CLASSES
from orientation.train import Epoch, fast_rollout
from test_orientation_model import random_net


@pytest.mark.parametrize("r", [1, 2, 9])
def test_the_stacked_rollout_is_each_members_own(r):
    nets = [random_net(10 * r + k) for k in range(3)]
    stacked = lopo.StackedNets(nets)
    g = torch.Generator().manual_seed(r)
    feats = torch.randn(3, 11, r, FRAME_INPUTS, generator=g)
    dyaw = 0.2 * torch.randn(3, 11, r, generator=g)
    prev0 = torch.nn.functional.normalize(torch.randn(3, 11, 2, generator=g), dim=-1)
    got = stacked.rollout(feats, dyaw, prev0)
    for k, net in enumerate(nets):
        want = fast_rollout(net, feats[k], dyaw[k], prev0[k])
        assert torch.allclose(got[k], want, atol=1e-5), (k, (got[k] - want).abs().max())
        member = stacked.member(k)
        x = torch.randn(5, NUM_INPUTS, generator=g)
        assert torch.allclose(member(x), net(x), atol=1e-6)
    # One member's loss moves only that member's weights.
    got[1].sum().backward()
    assert stacked.weights[0].grad[1].abs().sum() > 0
    assert stacked.weights[0].grad[0].abs().sum() == 0 and stacked.weights[0].grad[2].abs().sum() == 0


def test_a_fold_never_draws_a_window_of_its_person():
    ep = Epoch(np.zeros((10, FRAME_INPUTS), np.float32), np.zeros(10), np.zeros(10), np.arange(1, 9))
    shared = lopo.SharedEpoch(ep, np.array([0, 0, 0, 1, 1, 1, 2, 2, 2, 2]))
    assert set(shared.owner[lopo.fold_view(shared, 1).starts]) == {0, 2}
    assert len(lopo.fold_view(shared, None).starts) == 8


def test_people_come_from_the_manifest(mocap):
    people = data.people(mocap)
    assert len(people) >= 18, "the manifest's persons (it only grows)"
    # A person may span skeletons (CMU 02 is in both CMU conversions): one person, two databases.
    assert all(isinstance(f, list) and f for folders in people.values() for f in folders.values())
    with pytest.raises(data.DataError, match="no person nobody"):
        data.load_people(["nobody"])


def test_the_reduced_leave_one_person_out_run(tmp_path):
    """CI's form: four small people, two folds, a few batches. Every fold is scored on its own
    person only, in both conditions, and the table has a row per person and the mean; each
    fold's network is written as the page loads one (`--onnx`, the VR bench's `--lopo`); with
    `fit`, the network trained on everybody is scored on each fold's person too."""
    cfg = lopo.MODELS["main"]
    from dataclasses import replace

    cfg = replace(cfg, epochs=2, max_batches_per_epoch=30)
    names = ["cmu-05", "cmu-06", "cmu-10", "cmu-12"]
    res = lopo.run(names, ["cmu-05", "cmu-12"], cfg, jobs=2, log=lambda *_: None, onnx_dir=tmp_path, fit=True)
    import onnx

    assert list(res["fit"]) == ["cmu-05", "cmu-12"] and all(0 <= v < 90 for v in res["fit"].values()), res["fit"]

    for person in ("cmu-05", "cmu-12"):
        model = onnx.load(tmp_path / f"{person}.onnx")
        meta = {p.key: p.value for p in model.metadata_props}
        assert meta["held_out_person"] == person and person not in meta["trained_on"].split(",")
    for cond in lopo.CONDITIONS:
        per = res[cond]["people"]
        assert list(per) == ["cmu-05", "cmu-12"]
        for r in per.values():
            assert r["frames"] > 500 and np.isfinite(r["mean"]) and 0 <= r["mean"] <= 180
            assert set(r["classes"]) <= set(CLASSES)
        tot = res[cond]["total"]
        assert tot["mean"] == pytest.approx(np.mean([r["mean"] for r in per.values()]))
    text = lopo.table(res)
    assert "| cmu-05 |" in text and "| cmu-12 |" in text and "mean over 2 people" in text
    # A trained network beats a coin: far under the 90° of a random facing.
    assert res["without look-around"]["total"]["mean"] < 60


def test_the_temporal_consistency_loss_trains_and_the_jerk_is_scored():
    """`TrainConfig.smooth` (an experiment): the run still trains and scores; every person gets
    a finite yaw jerk (mean |second difference|), and the totals carry its mean."""
    from dataclasses import replace

    cfg = replace(lopo.MODELS["main"], epochs=1, max_batches_per_epoch=10, smooth=1.0)
    res = lopo.run(["cmu-05", "cmu-06", "cmu-10"], ["cmu-05"], cfg, jobs=1, log=lambda *_: None)
    for cond in lopo.CONDITIONS:
        r = res[cond]["people"]["cmu-05"]
        assert np.isfinite(r["mean"]) and np.isfinite(r["jerk"]) and r["jerk"] > 0
        assert res[cond]["total"]["jerk"] == pytest.approx(r["jerk"])
