"""The Scaffold-GS MLP files of a checkpoint folder: traced heads or a weights-only state dict.

Official layout (github.com/city-super/Scaffold-GS, ``scene/gaussian_model.py``
``save_mlp_checkpoints`` / ``load_mlp_checkpoints``, default mode "split"): each head is
``torch.jit.trace``d in eval mode and saved as ``opacity_mlp.pt`` (Linear, ReLU, Linear, Tanh),
``cov_mlp.pt`` (Linear, ReLU, Linear) and ``color_mlp.pt`` (Linear, ReLU, Linear, Sigmoid);
with ``appearance_dim > 0`` the appearance ``Embedding`` wrapper is traced into
``embedding_appearance.pt`` (key ``embedding.weight``); ``feature_bank_mlp.pt`` exists only with
``use_feat_bank``. Mode "unite" saves one state dict ``checkpoints.pth`` with keys
``opacity_mlp cov_mlp color_mlp [appearance] [feature_bank_mlp]``; HAC and older Scaffold-GS
save ``checkpoint.pth`` (same head keys). Heads keep ``nn.Sequential`` keys ``0.weight 0.bias
2.weight 2.bias``.

Nothing in a file is executed: traced modules are loaded with ``torch.jit.load`` and only their
weights are kept, after checking their graph is the plain head chain; state dicts are loaded
with ``torch.load(weights_only=True)``.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.interchange.anchor_ply import read_bytes
from csgs_codec.scene.anchor_scene import HEADS, MLPWeights, ScaffoldMLPWeights

HEAD_FILES = {"opacity": "opacity_mlp.pt", "cov": "cov_mlp.pt", "color": "color_mlp.pt"}
APPEARANCE_FILE = "embedding_appearance.pt"
FEATURE_BANK_FILE = "feature_bank_mlp.pt"
#: State-dict files: Scaffold-GS "unite" mode, then older Scaffold-GS and HAC.
STATE_DICT_FILES = ("checkpoints.pth", "checkpoint.pth")
#: Largest MLP file accepted (real ones are tens of KiB).
MAX_MLP_FILE_BYTES = 64 << 20
_TORCH_ACTIVATIONS = {"tanh": "aten::tanh", "sigmoid": "aten::sigmoid", "none": None}


# =========================================================================== reading
def read_scaffold_mlps(folder: str | Path, *, required: bool = True
                       ) -> ScaffoldMLPWeights | None:
    """Read the MLP weights of a checkpoint folder (traced ``*_mlp.pt`` or a state dict).

    Raises:
        InputError: missing or malformed file (naming it and the missing key as property).
        UnsupportedError: feature-bank checkpoints, non-standard head graphs.
    """
    folder = Path(folder)
    if (folder / FEATURE_BANK_FILE).exists():
        raise UnsupportedError("feature-bank Scaffold-GS checkpoints (use_feat_bank) are not "
                               "supported", file=folder / FEATURE_BANK_FILE)
    present = [name for name, f in HEAD_FILES.items() if (folder / f).exists()]
    if present:
        for name, f in HEAD_FILES.items():
            if name not in present:
                raise InputError("MLP file missing (the other heads are present)",
                                 file=folder / f, property=name)
        heads = {name: _read_traced_head(folder / f, HEADS[name][1])
                 for name, f in HEAD_FILES.items()}
        appearance = None
        if (folder / APPEARANCE_FILE).exists():
            appearance = _read_traced_embedding(folder / APPEARANCE_FILE)
        return ScaffoldMLPWeights(appearance=appearance, **heads)
    for f in STATE_DICT_FILES:
        if (folder / f).exists():
            return _read_state_dict_file(folder / f)
    if required:
        raise InputError(f"no MLP weights: expected {', '.join(HEAD_FILES.values())} or "
                         f"{' / '.join(STATE_DICT_FILES)}", file=folder / HEAD_FILES["opacity"])
    return None


def _load_torchscript(path: Path):
    import torch

    data = read_bytes(path, MAX_MLP_FILE_BYTES)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            return torch.jit.load(io.BytesIO(data), map_location="cpu")
    except Exception as exc:
        raise InputError(f"not a TorchScript module ({type(exc).__name__})", file=path) from None


def _graph_ops(module) -> list[str]:
    skip = {"prim::GetAttr", "prim::Constant", "prim::ListConstruct"}
    return [n.kind() for n in module.inlined_graph.nodes() if n.kind() not in skip]


def _tensor_array(state: dict, key: str, ndim: int, path: Path) -> np.ndarray:
    import torch

    value = state.get(key)
    if not isinstance(value, torch.Tensor):
        raise InputError("tensor missing", file=path, property=key)
    if not value.is_floating_point() or value.ndim != ndim:
        raise InputError(f"expected a {ndim}-D float tensor, got {tuple(value.shape)} "
                         f"{value.dtype}", file=path, property=key)
    return value.detach().to(torch.float32).cpu().numpy().copy()


def _head_from_state(state: dict, path: Path) -> MLPWeights:
    return MLPWeights(w1=_tensor_array(state, "0.weight", 2, path),
                      b1=_tensor_array(state, "0.bias", 1, path),
                      w2=_tensor_array(state, "2.weight", 2, path),
                      b2=_tensor_array(state, "2.bias", 1, path))


def _read_traced_head(path: Path, activation: str) -> MLPWeights:
    module = _load_torchscript(path)
    expected = ["aten::linear", "aten::relu", "aten::linear", _TORCH_ACTIVATIONS[activation]]
    ops = [op.rstrip("_") for op in _graph_ops(module)]
    if ops != [op for op in expected if op is not None]:
        raise UnsupportedError(f"graph {ops} is not the Scaffold-GS head "
                               f"(linear, relu, linear, {activation})", file=path)
    return _head_from_state(module.state_dict(), path)


def _read_traced_embedding(path: Path) -> np.ndarray:
    module = _load_torchscript(path)
    if _graph_ops(module) != ["aten::embedding"]:
        raise UnsupportedError("graph is not an embedding lookup", file=path)
    state = module.state_dict()
    if len(state) != 1:
        raise InputError(f"expected one embedding table, found {list(state)}", file=path)
    return _tensor_array(state, next(iter(state)), 2, path)


def _read_state_dict_file(path: Path) -> ScaffoldMLPWeights:
    import torch

    data = read_bytes(path, MAX_MLP_FILE_BYTES * 4)
    try:
        with warnings.catch_warnings():
            # Old pickle protocols make torch warn before the weights-only unpickler rejects
            # or accepts them; the outcome is what counts.
            warnings.simplefilter("ignore", UserWarning)
            state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as exc:
        raise InputError(f"not a weights-only torch state dict ({type(exc).__name__})",
                         file=path) from None
    if not isinstance(state, dict):
        raise InputError("expected a dict of state dicts", file=path)
    for key in ("feature_bank_mlp", "mlp_feature_bank"):
        if key in state:
            raise UnsupportedError("feature-bank checkpoints are not supported", file=path,
                                   property=key)
    heads = {}
    for name in HEAD_FILES:
        sub = state.get(f"{name}_mlp")
        if not isinstance(sub, dict):
            raise InputError("head state dict missing", file=path, property=f"{name}_mlp")
        heads[name] = _head_from_state(dict(sub), path)
    appearance = None
    if isinstance(state.get("appearance"), dict):
        appearance = _tensor_array(state["appearance"], "embedding.weight", 2, path)
    return ScaffoldMLPWeights(appearance=appearance, **heads)


# =========================================================================== writing
def mlp_file_bytes(mlps: ScaffoldMLPWeights) -> dict[str, bytes]:
    """The traced head files ("split" mode) keyed by file name."""
    files = {HEAD_FILES[name]: _traced_head_bytes(weights, HEADS[name][1])
             for name, weights in mlps.heads().items()}
    if mlps.appearance is not None:
        files[APPEARANCE_FILE] = _traced_embedding_bytes(mlps.appearance)
    return files


def _trace_to_bytes(module, example) -> bytes:
    import torch

    buffer = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        traced = torch.jit.trace(module.eval(), (example,))
        torch.jit.save(traced, buffer)
    return buffer.getvalue()


def _traced_head_bytes(weights: MLPWeights, activation: str) -> bytes:
    import torch
    from torch import nn

    layers = [nn.Linear(weights.in_dim, weights.w1.shape[0]), nn.ReLU(True),
              nn.Linear(weights.w1.shape[0], weights.out_dim)]
    layers += {"tanh": [nn.Tanh()], "sigmoid": [nn.Sigmoid()], "none": []}[activation]
    module = nn.Sequential(*layers)
    with torch.no_grad():
        for layer, (w, b) in ((layers[0], (weights.w1, weights.b1)),
                              (layers[2], (weights.w2, weights.b2))):
            layer.weight.copy_(torch.from_numpy(w))
            layer.bias.copy_(torch.from_numpy(b))
    return _trace_to_bytes(module, torch.zeros(1, weights.in_dim))


def _traced_embedding_bytes(table: np.ndarray) -> bytes:
    import torch
    from torch import nn

    class _AppearanceEmbedding(nn.Module):
        # Same state-dict key ("embedding.weight") as the official Embedding wrapper.
        def __init__(self) -> None:
            super().__init__()
            self.embedding = nn.Embedding(table.shape[0], table.shape[1])

        def forward(self, index):
            return self.embedding(index)

    module = _AppearanceEmbedding()
    with torch.no_grad():
        module.embedding.weight.copy_(torch.from_numpy(table))
    return _trace_to_bytes(module, torch.zeros((1,), dtype=torch.long))
