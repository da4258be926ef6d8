"""The orientation MLP, the r-step feedback rollout, and ONNX export.

Network (docs/method.md §9): 54 inputs (the thesis's 42 and a context: features.py) → hidden layers with a ReLU after **each** → 6 + 2:
the 6D body rotation and where the hips are from the head (`features.hips_target`). The
thesis's size is 2 × 32 (the released MMVR model has a ReLU after the first hidden layer only);
the hidden sizes are a training parameter here (`TrainConfig.hidden`), chosen by held-out error
within the browser's time budget (docs/orientation-model.md, "Model size").
Input normalization (x − mean) / std is part of the module, so the exported ONNX graph takes the
raw features of `features.py` — a runtime needs no statistics file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from .features import FEATURE_NAMES, FRAME_COLUMNS, HIPS_OUTPUTS, NUM_INPUTS, PREV, TRACKER_INPUTS

HIDDEN = 32
_FRAME_COLUMNS = torch.as_tensor(FRAME_COLUMNS)
INPUT_NAME, OUTPUT_NAME, HIPS_NAME = "features", "orientation6d", "hips"
# The outputs: the 6D, then the hips (a model from before the hips has the 6D only).
NUM_OUTPUTS = 6 + HIPS_OUTPUTS


class OrientationNet(nn.Module):
    def __init__(
        self,
        mean: np.ndarray | None = None,
        std: np.ndarray | None = None,
        hidden: tuple[int, ...] = (HIDDEN, HIDDEN),
        inputs: int = NUM_INPUTS,
        outputs: int = NUM_OUTPUTS,
    ):
        super().__init__()
        self.inputs = inputs  # 54, or 42 for a model from before the context
        self.outputs = outputs  # 8, or 6 for a model from before the hips
        self.register_buffer("mean", torch.zeros(inputs))
        self.register_buffer("inv_std", torch.ones(inputs))
        if mean is not None:
            self.set_normalization(mean, std)
        self.hidden = tuple(hidden)
        layers, width = [], inputs
        for h in self.hidden:
            layers += [nn.Linear(width, h), nn.ReLU()]
            width = h
        self.mlp = nn.Sequential(*layers, nn.Linear(width, outputs))

    def set_normalization(self, mean: np.ndarray, std: np.ndarray) -> None:
        """Dimensions that never vary (the constant parts of the previous-orientation 6D) get
        scale 1 rather than 1/0, so garbage there stays bounded."""
        std = np.where(np.asarray(std) > 1e-4, std, 1.0)
        self.mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
        self.inv_std.copy_(torch.as_tensor(1.0 / std, dtype=torch.float32))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.mlp((x - self.mean) * self.inv_std)


class AveragedNet(nn.Module):
    """Several `OrientationNet`s of one recipe (different first weights and windows) on the same
    input, their outputs averaged: one input, one output, the file's contract unchanged. Each
    member errs its own way on a person none of them saw; the mean errs less (leave-one-person-
    out, README "Judged person by person": two members 10.8° → 10.4° with look-around, 9.9° →
    9.5° without, against each member alone). The runtime feeds the mean back to all of them,
    which scores the same as each feeding back its own. Written as a sum and one scale so the
    graph keeps to Gemm/Relu/Add/Mul."""

    def __init__(self, members: list[OrientationNet]):
        super().__init__()
        if not members:
            raise ValueError("AveragedNet needs at least one member")
        self.members = nn.ModuleList(members)
        self.inputs, self.outputs, self.hidden = members[0].inputs, members[0].outputs, members[0].hidden

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = self.members[0](x)
        for m in self.members[1:]:
            out = out + m(x)
        return out * (1.0 / len(self.members)) if len(self.members) > 1 else out


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v * torch.rsqrt((v * v).sum(-1, keepdim=True) + 1e-8)


def rollout(
    net: OrientationNet, feats: torch.Tensor, dyaw: torch.Tensor, prev0: torch.Tensor, steps: int | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Run the network `r` frames feeding back its own prediction (thesis Fig. "Orientation
    Prediction Training"): the previous-orientation slot of step t is step t−1's prediction,
    reduced to its yaw and re-expressed in step t's HMD-yaw frame (exactly what the runtime
    feeds back). Gradients flow through the whole chain, so the network learns to use its own
    earlier estimates and to recover from poor ones.

    feats (B, r, 48) frame features (`features.frame_features`); dyaw (B, r) HMD yaw change into each frame (dyaw[:, 0]
    unused); prev0 (B, 2) = (cos φ, sin φ) of the previous body yaw relative to frame 0's HMD
    yaw. Returns (last output (B, outputs), all outputs (B, r, outputs)).
    """
    r = feats.shape[1] if steps is None else steps
    cs = prev0
    zeros, ones = torch.zeros_like(cs[:, :1]), torch.ones_like(cs[:, :1])
    outs = []
    for t in range(r):
        if t > 0:
            # φ_t = φ_{t−1} − Δψ: rotate (cos, sin) by −Δψ.
            c, s = torch.cos(dyaw[:, t : t + 1]), torch.sin(dyaw[:, t : t + 1])
            cs = torch.cat([cs[:, :1] * c + cs[:, 1:] * s, cs[:, 1:] * c - cs[:, :1] * s], dim=1)
        prev6 = torch.cat([cs[:, :1], zeros, -cs[:, 1:], zeros, ones, zeros], dim=1)
        x = torch.empty(feats.shape[0], NUM_INPUTS, dtype=feats.dtype, device=feats.device)
        x[:, _FRAME_COLUMNS.to(feats.device)], x[:, PREV] = feats[:, t], prev6
        out = net(x)
        outs.append(out)
        cs = _unit(torch.stack([out[:, 0], -out[:, 2]], dim=1))
    return outs[-1], torch.stack(outs, dim=1)


def state_to_numpy(net: OrientationNet) -> dict[str, np.ndarray]:
    return {k: v.detach().cpu().numpy().copy() for k, v in net.state_dict().items()}


def net_from_state(state: dict) -> OrientationNet | AveragedNet:
    """The network of a saved state dict (hidden sizes read off the weight shapes): an
    `AveragedNet` where the keys are its members' (`members.<k>.…`)."""
    if any(k.startswith("members.") for k in state):
        count = 1 + max(int(k.split(".")[1]) for k in state if k.startswith("members."))
        return AveragedNet(
            [
                net_from_state(
                    {k[len(f"members.{i}.") :]: v for k, v in state.items() if k.startswith(f"members.{i}.")}
                )
                for i in range(count)
            ]
        ).eval()
    weights = sorted(
        (k for k in state if k.startswith("mlp.") and k.endswith(".weight")), key=lambda k: int(k.split(".")[1])
    )
    hidden = tuple(int(np.asarray(state[k]).shape[0]) for k in weights[:-1])
    outputs = int(np.asarray(state[weights[-1]]).shape[0])
    net = OrientationNet(hidden=hidden, inputs=int(np.asarray(state["mean"]).shape[0]), outputs=outputs)
    net.load_state_dict({k: torch.as_tensor(np.asarray(v)) for k, v in state.items()})
    return net.eval()


class _SplitOutputs(nn.Module):
    """The network with its output cut in two for export: the 6D, then the hips."""

    def __init__(self, net: nn.Module):
        super().__init__()
        self.net, self.inputs = net, net.inputs

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out = self.net(x)
        return out[:, :6], out[:, 6:]


def export_onnx(net: nn.Module, path: Path, metadata: dict[str, str] | None = None, state_size: int = 0) -> Path:
    """Write the model as one self-contained ONNX file (weights embedded, no `.onnx.data`),
    input `features` float32 [batch, 54] raw, outputs `orientation6d` float32 [batch, 6] and
    `hips` float32 [batch, 2] (`features.hips_target`; a network without it: the 6D only). A
    recurrent model (`state_size` > 0: `gru.GruStep`) takes `features` [batch, 36] and `state`
    [batch, state_size] and also outputs `state_out` [batch, state_size]."""
    import onnx

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    net = net.eval()
    batch = torch.export.Dim("batch", min=1, max=1 << 20)
    if state_size:
        example = (torch.zeros(1, TRACKER_INPUTS), torch.zeros(1, state_size))
        names, outputs, dims = [INPUT_NAME, "state"], [OUTPUT_NAME, "state_out"], ({0: batch}, {0: batch})
    else:
        example, names, outputs, dims = (torch.zeros(1, net.inputs),), [INPUT_NAME], [OUTPUT_NAME], ({0: batch},)
        if getattr(net, "outputs", 6) > 6:
            net, outputs = _SplitOutputs(net).eval(), [OUTPUT_NAME, HIPS_NAME]
    program = torch.onnx.export(
        net,
        example,
        input_names=names,
        output_names=outputs,
        dynamo=True,
        external_data=False,
        opset_version=18,
        dynamic_shapes=dims,
        verbose=False,
        report=False,
    )
    model = program.model_proto
    # The exporter annotates every value and node (source locations, export bookkeeping): half
    # the file for a model this small, and nothing a runtime reads.
    del model.graph.value_info[:]
    for node in model.graph.node:
        del node.metadata_props[:]
        node.doc_string = ""
    for value in list(model.graph.input) + list(model.graph.output) + list(model.graph.initializer):
        del value.metadata_props[:]
    model.doc_string = (
        f"Body-orientation network (docs/method.md §9). Input: {net.inputs} raw features "
        "(docs/orientation-model.md); outputs: 6D body rotation in the HMD-yaw frame"
        + ("; the hips from the head centre on the floor (x, z) in that frame, m." if len(outputs) > 1 else ".")
        if not state_size
        else "Recurrent body-orientation network (docs/orientation-model.md). Inputs: the 36 "
        "raw tracker features and the state (zeros after a reset); outputs: 6D body "
        "rotation in the HMD-yaw frame and the next state."
    )
    props = {
        "feature_order": ",".join(FEATURE_NAMES[: TRACKER_INPUTS if state_size else net.inputs]),
        "units": "m, s, rad; Y up; yaw 0 = +Z",
        **(metadata or {}),
    }
    del model.metadata_props[:]
    for k, v in props.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, str(v)
    onnx.checker.check_model(model, full_check=True)
    onnx.save_model(model, str(path), save_as_external_data=False)
    return path
