"""The network, its training rollout, and the committed ONNX model's format and parity."""

import hashlib
import json

import numpy as np
import onnx
import pytest
import torch

from orientation.features import FEATURE_NAMES, FRAME_INPUTS, NUM_INPUTS
from orientation.fixtures import FIXTURE
from orientation.model import HIPS_NAME, INPUT_NAME, OUTPUT_NAME, OrientationNet, net_from_state, rollout
from orientation.predictors import OnnxModel, TorchModel
from orientation.train import MODELS_DIR, PUBLIC_MODEL, fast_rollout


def random_net(seed=0):
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = OrientationNet(rng.normal(0, 1, NUM_INPUTS), np.abs(rng.normal(1, 0.3, NUM_INPUTS)))
    for p in net.parameters():
        p.data.normal_(0, 0.4)
    return net


def test_relu_after_each_hidden_layer():
    # docs/method.md §9: 54 → 32 → ReLU → 32 → ReLU → 6 + 2, the 6D and the hips (the released
    # MMVR model misses one ReLU, and has no hips).
    kinds = [type(m).__name__ for m in OrientationNet().mlp]
    assert kinds == ["Linear", "ReLU", "Linear", "ReLU", "Linear"]
    shapes = [tuple(m.weight.shape) for m in OrientationNet().mlp if hasattr(m, "weight")]
    assert shapes == [(32, NUM_INPUTS), (32, 32), (8, 32)] and NUM_INPUTS == 54


@pytest.mark.parametrize("r", [1, 2, 9])
def test_fast_rollout_equals_the_plain_rollout(r):
    net = random_net(r)
    g = torch.Generator().manual_seed(r)
    feats = torch.randn(11, r, FRAME_INPUTS, generator=g)
    dyaw = 0.2 * torch.randn(11, r, generator=g)
    prev0 = torch.nn.functional.normalize(torch.randn(11, 2, generator=g), dim=1)
    want, _ = rollout(net, feats, dyaw, prev0)
    for through in (False, True):
        got = fast_rollout(net, feats, dyaw, prev0, grad_through=through)
        assert torch.allclose(got, want, atol=1e-5), (r, through, (got - want).abs().max())
    # Without grad_through only the last step carries gradient, with it every step does.
    got = fast_rollout(net, feats, dyaw, prev0.requires_grad_(True), grad_through=True)
    got.sum().backward()
    assert prev0.grad is not None and (r == 1 or prev0.grad.abs().sum() > 0)


def test_normalization_is_inside_the_model():
    net = random_net(3)
    x = torch.randn(5, NUM_INPUTS)
    manual = net.mlp((x - net.mean) * net.inv_std)
    assert torch.allclose(net(x), manual)
    const = OrientationNet(np.zeros(NUM_INPUTS), np.zeros(NUM_INPUTS))
    assert torch.all(const.inv_std == 1.0), "constant inputs are not divided by ~0"


# ---------------------------------------------------------------- the committed model


def _committed():
    if not PUBLIC_MODEL.is_file():
        pytest.fail(f"{PUBLIC_MODEL} missing: run `npm run train`")
    return onnx.load(str(PUBLIC_MODEL))


def test_committed_onnx_is_small_self_contained_and_documented():
    model = _committed()
    assert PUBLIC_MODEL.stat().st_size < 64 * 1024
    assert not list(PUBLIC_MODEL.parent.glob("*.data")), "no external-data side file"
    for init in model.graph.initializer:
        assert init.data_location != onnx.TensorProto.EXTERNAL, init.name
    onnx.checker.check_model(model, full_check=True)
    (inp,), (out, hips) = model.graph.input, model.graph.output
    assert inp.name == INPUT_NAME and out.name == OUTPUT_NAME and hips.name == HIPS_NAME
    dims = lambda v: [d.dim_value or d.dim_param for d in v.type.tensor_type.shape.dim]  # noqa: E731
    assert dims(inp)[1:] == [NUM_INPUTS] and dims(out)[1:] == [6] and dims(hips)[1:] == [2]
    assert isinstance(dims(inp)[0], str), "batch dimension is dynamic"
    assert inp.type.tensor_type.elem_type == onnx.TensorProto.FLOAT
    meta = {p.key: p.value for p in model.metadata_props}
    assert meta["feature_order"].split(",") == FEATURE_NAMES
    assert meta["r"] == "50" and meta["look_around"] == "True"
    assert {n.op_type for n in model.graph.node} <= {"Sub", "Mul", "Gemm", "Relu", "MatMul", "Add", "Slice"}


def test_committed_onnx_equals_pytorch():
    _committed()
    net = net_from_state(dict(np.load(MODELS_DIR / "orientation_main.npz")))
    fixture = json.loads(FIXTURE.read_text())
    assert fixture["model_sha256"] == hashlib.sha256(PUBLIC_MODEL.read_bytes()).hexdigest(), (
        "fixture is stale: regenerate with `npm run train` (or python -m orientation.fixtures)"
    )
    rows = np.array(fixture["rows"]["inputs"], dtype=np.float32)
    onnx_out = OnnxModel(PUBLIC_MODEL)(rows)
    torch_out = TorchModel(net)(rows)
    # Relative as well as absolute: outputs reach ~50, where a float32 ulp is 4e-6, and the two
    # runtimes sum in a different order on each CPU (3 ulps apart on an AMD EPYC). A wrong weight
    # or layer is off by far more.
    np.testing.assert_allclose(onnx_out, torch_out, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(torch_out, np.array(fixture["rows"]["outputs"]), rtol=1e-5, atol=1e-5)
    seq_in = np.array(fixture["sequence"]["inputs"], dtype=np.float32)
    assert np.abs(OnnxModel(PUBLIC_MODEL)(seq_in) - np.array(fixture["sequence"]["outputs"])).max() < 1e-5
