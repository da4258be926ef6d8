"""The recurrent (GRU) experiment stays runnable: a short training on one small subject lowers
its loss, and the frame-by-frame runner is causal (a prefix of a take gets the same yaws as the
whole take) and finite. Its held-out numbers are in the README ("Body-orientation network")."""

import numpy as np
import torch

from orientation import data
from orientation.gru import GruConfig, run_gru, train_gru
from orientation.predictors import sequence_features
from orientation.simulate import EVAL_AUGMENT, simulate


def test_a_short_gru_training_learns_and_runs_causally(mocap, mmdb_cli):
    clips = data.load_subjects((("cmu-daz", "05"),), mirrored=None)
    log = []
    net = train_gru(
        GruConfig(hidden=16, window=60, burn_in=10, epochs=3, max_batches_per_epoch=40), clips, log=log.append
    )
    losses = [float(line.split("loss ")[1].split()[0]) for line in log]
    assert losses[-1] < 0.8 * losses[0], losses
    seq = simulate(clips[0], np.random.default_rng(3), EVAL_AUGMENT, fps=90.0)
    feats, hmd, _ = sequence_features([seq])
    whole = run_gru(net, feats, hmd, chunk=64)
    part = run_gru(net, feats[:, :100], hmd[:, :100], chunk=7)
    assert np.isfinite(whole).all()
    np.testing.assert_allclose(part, whole[:, :100], atol=1e-4)
    assert isinstance(net.gru, torch.nn.GRU)
