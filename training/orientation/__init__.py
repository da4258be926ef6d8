"""Body-orientation network (docs/method.md §9, thesis §"Prediction of the body orientation").

From full-body mocap (`.mmdb` files the Rust builder writes, read with `mmdb.py`) this package
simulates what a VR user's headset and two controllers report, turns it into the 54 network
inputs, trains the small MLP with the r-step feedback rollout (two of them, averaged:
`model.AveragedNet`), exports it to ONNX and evaluates it against simple baselines. The
input/output contract is in `docs/orientation-model.md`; `web/src/orientation/` is the browser
twin of `features.py` and `predictors.py`.

Modules: `geometry` (quaternions, yaw), `data` (subjects, databases, clips), `simulate`
(trackers + augmentations), `features` (the 54 inputs), `model` (MLP, rollout, ONNX export),
`predictors` (runtime feedback loop and baselines), `train`, `evaluate`.
"""
