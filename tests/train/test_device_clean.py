"""Training, rendering and model code create every tensor on the device of their inputs.

A CUDA run once crashed in ``row_bands`` because ``torch.zeros(height + 1, ...)`` made a CPU
tensor next to CUDA ones (issue #31). Two checks keep that class of bug out, both on the CPU:

* a static rule over ``csgs_codec/render``, ``csgs_codec/train``, ``csgs_codec/model`` and
  ``csgs_codec/bake`` (:func:`device_rule_violations`):

  1. every call of a torch tensor factory (:data:`FACTORIES`: ``torch.zeros``, ``arange``,
     ``tensor``, ``as_tensor``, ``rand``..., and ``torch.Generator``) and of a ``torch.nn``
     layer that takes a ``device`` (``nn.Linear``, ``nn.Embedding``...) passes a ``device=``
     keyword, and not the literal None. The ``*_like`` and ``Tensor.new_*`` factories inherit
     their input's device and are fine;
  2. ``torch.from_numpy`` and ``torch.frombuffer`` always make CPU tensors: use
     ``torch.as_tensor(array, device=...)`` instead;
  3. a deliberate CPU placement, a literal ``"cpu"`` device (``device="cpu"``,
     ``torch.device("cpu")``, ``.to("cpu")``), and rule 2's functions, are accepted only with
     a trailing ``# cpu: <why>`` comment on one of the call's lines. A factory call without
     ``device=`` is never accepted, whatever its comment.

  Default values of ``device`` parameters are the caller's choice and are not checked.

* a behavioural check: the whole training pipeline (stage 1 with growth, pruning and the
  rate term, a checkpoint reloaded, the encoder's hyperprior fits, stages 2 and 3), renders
  and their gradients through the pure-torch rasterizer, and the color hyperprior fit, run
  under ``torch.set_default_device("meta")`` with every input on the CPU. A tensor made
  without an explicit device then lands on the meta device, and mixing it with the CPU
  tensors (or reading its values) fails loudly. Code outside the checked folders that relies
  on the CPU default gets it back (:func:`others_on_the_cpu_default`).
"""

from __future__ import annotations

import ast
import contextlib
import functools
import inspect
import io
import re
import tokenize
from pathlib import Path

import numpy as np
import pytest
import torch

from csgs_codec.chunks.color_prior import MEAN_BITS, MEAN_LIMIT
from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.model.color_hyperprior import ColorFitSettings, ColorPriorFit
from csgs_codec.render.composite_torch import composite
from csgs_codec.render.jacobian_sensitivity import jacobian_sensitivity
from csgs_codec.render.rasterize_torch import prepare_gaussians, rasterize_gaussians
from csgs_codec.render.rasterizer import render, scene_tensors
from csgs_codec.render.tiles import depth_order
from csgs_codec.train.checkpoint import load_checkpoint
from csgs_codec.train.pipeline import CHECKPOINT_FILE, train_scene
from tests.train.stage1_data import tiny_dataset, tiny_train_settings

REPO = Path(__file__).resolve().parents[2]
#: Folders whose code must be device clean.
CHECKED = ("csgs_codec/render", "csgs_codec/train", "csgs_codec/model", "csgs_codec/bake")

#: torch functions that make a tensor (or generator) from scratch: without ``device=`` they
#: use the default device, whatever device the surrounding computation is on.
FACTORIES = frozenset({
    "arange", "as_tensor", "asarray", "bartlett_window", "blackman_window", "empty",
    "empty_strided", "eye", "full", "hamming_window", "hann_window", "kaiser_window",
    "linspace", "logspace", "normal", "ones", "rand", "randint", "randn", "randperm", "range",
    "scalar_tensor", "sparse_coo_tensor", "sparse_csr_tensor", "tensor", "tril_indices",
    "triu_indices", "zeros", "Generator",
})
#: torch functions whose tensor is always on the CPU.
HOST_ONLY = frozenset({"from_numpy", "frombuffer"})
CPU_COMMENT = re.compile(r"#\s*cpu:\s*\S")


def _aliases(tree: ast.Module) -> dict[str, str]:
    """Local name -> dotted torch name, from the module's imports of torch."""
    names = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == "torch" or alias.name.startswith("torch."):
                    if alias.asname:
                        names[alias.asname] = alias.name
                    else:
                        names[alias.name.split(".")[0]] = alias.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom) and node.module and (
                node.module == "torch" or node.module.startswith("torch.")):
            for alias in node.names:
                names[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    return names


def _dotted(node: ast.expr, aliases: dict[str, str]) -> str | None:
    """The dotted torch name ``node`` refers to, or None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name) or node.id not in aliases:
        return None
    return ".".join([aliases[node.id]] + parts[::-1])


def _takes_device(dotted: str) -> bool:
    """Whether ``dotted`` is a ``torch.nn`` module class whose constructor takes a device."""
    if not dotted.startswith("torch.nn."):
        return False
    target = torch
    for part in dotted.split(".")[1:]:
        target = getattr(target, part, None)
        if target is None:
            return False
    if not (inspect.isclass(target) and issubclass(target, torch.nn.Module)):
        return False
    return "device" in inspect.signature(target.__init__).parameters


def _is_cpu(node: ast.expr | None) -> bool:
    return (isinstance(node, ast.Constant) and isinstance(node.value, str)
            and node.value.split(":")[0] == "cpu")


def _commented_lines(source: str) -> set[int]:
    lines = set()
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT and CPU_COMMENT.match(token.string):
            lines.add(token.start[0])
    return lines


def _needs_device(dotted: str) -> bool:
    name = dotted.removeprefix("torch.")
    return (name in FACTORIES and dotted.count(".") == 1) or _takes_device(dotted)


def _passed_uncalled(call: ast.Call, aliases: dict[str, str]) -> str | None:
    """A factory handed to ``call`` to be called later (``default_factory=torch.Generator``,
    ``partial(torch.zeros, ...)``): those calls cannot name a device. (Classes passed as
    positional values, as in ``isinstance`` or type lists, are not calls.)"""
    values = [k.value for k in call.keywords]
    func = call.func.attr if isinstance(call.func, ast.Attribute) else getattr(call.func, "id",
                                                                                None)
    if func == "partial":
        values += call.args[:1]
    for value in values:
        dotted = _dotted(value, aliases)
        if dotted is not None and (_needs_device(dotted)
                                   or dotted.removeprefix("torch.") in HOST_ONLY):
            return f"{dotted} passed uncalled: its calls cannot name a device"
    return None


def _call_problem(call: ast.Call, aliases: dict[str, str]) -> tuple[str | None, bool]:
    """(what is wrong with ``call``, whether a ``# cpu:`` comment excuses it)."""
    uncalled = _passed_uncalled(call, aliases)
    if uncalled is not None:
        return uncalled, False
    keywords = {k.arg: k.value for k in call.keywords if k.arg is not None}
    has_kwargs = any(k.arg is None for k in call.keywords)
    device = keywords.get("device")
    dotted = _dotted(call.func, aliases)
    if isinstance(call.func, ast.Attribute) and call.func.attr == "to" and call.args \
            and _is_cpu(call.args[0]):
        return ".to('cpu') without a '# cpu: <why>' comment", True
    if _is_cpu(device):
        return "device='cpu' without a '# cpu: <why>' comment", True
    if dotted is None:
        return None, False
    name = dotted.removeprefix("torch.")
    if dotted == "torch.device" and call.args and _is_cpu(call.args[0]):
        return "torch.device('cpu') without a '# cpu: <why>' comment", True
    if name in HOST_ONLY:
        return (f"{dotted} makes a CPU tensor: use torch.as_tensor(..., device=...) (or mark "
                "a deliberate CPU tensor '# cpu: <why>')"), True
    needs_device = _needs_device(dotted)
    if name == "normal" and len(call.args) < 3 and "size" not in keywords:
        needs_device = False  # normal(mean_tensor, std_tensor) follows its inputs
    if not needs_device or has_kwargs:
        return None, False
    if device is None:
        return f"{dotted}(...) without device=", False
    if isinstance(device, ast.Constant) and device.value is None:
        return f"{dotted}(..., device=None)", False
    return None, False


def device_rule_violations(source: str, name: str) -> list[str]:
    """``name:line: problem`` for every call in ``source`` that breaks the module's rule."""
    tree = ast.parse(source)
    aliases = _aliases(tree)
    commented = _commented_lines(source)
    problems = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        problem, excusable = _call_problem(node, aliases)
        if problem is None:
            continue
        lines = range(node.lineno, (node.end_lineno or node.lineno) + 1)
        if excusable and commented.intersection(lines):
            continue
        problems.append((node.lineno, f"{name}:{node.lineno}: {problem}"))
    return [problem for _, problem in sorted(problems)]


def _checked_files() -> list[Path]:
    return sorted(p for folder in CHECKED for p in (REPO / folder).glob("*.py"))


def test_every_tensor_factory_names_its_device():
    problems = [p for path in _checked_files()
                for p in device_rule_violations(path.read_text(encoding="utf-8"),
                                                str(path.relative_to(REPO)))]
    assert not problems, "tensors made without an explicit device:\n" + "\n".join(problems)


@pytest.mark.parametrize(("snippet", "flagged"), [
    ("import torch\nx = torch.zeros(3)", True),
    ("import torch\nx = torch.zeros(3, device=y.device)", False),
    ("import torch\nx = torch.zeros(3, device=None)", True),
    ("import torch\nx = torch.zeros_like(y)", False),
    ("import torch as t\nx = t.arange(3)", True),
    ("from torch import tensor\nx = tensor([1.0])", True),
    ("import torch\ng = torch.Generator()", True),
    ("import torch\ng = torch.Generator(device='cpu')", True),
    ("import torch\ng = torch.Generator(device='cpu')  # cpu: the order is device free", False),
    ("import torch\nx = torch.from_numpy(a).to(d)", True),
    ("import torch\nx = torch.from_numpy(a)  # cpu: numpy in, numpy out", False),
    ("import torch\nx = torch.zeros(3)  # cpu: no device at all", True),
    ("import torch\nx = y.to('cpu')", True),
    ("from torch import nn\nm = nn.Linear(2, 3)", True),
    ("from torch import nn\nm = nn.Linear(2, 3, device=d)", False),
    ("from torch import nn\nm = nn.ReLU()", False),
    ("import torch\nm = torch.nn.Sequential(torch.nn.Tanh())", False),
    ("import torch\nx = torch.normal(mean, std)", False),
    ("import torch\nx = torch.normal(0.0, 1.0, (3,))", True),
    ("import numpy as np\nx = np.zeros(3)", False),
    ("import torch\ng = field(default_factory=torch.Generator)", True),
    ("import torch\nok = isinstance(g, torch.Generator)", False),
    ("import functools, torch\nf = functools.partial(torch.zeros, 3)", True),
    ("import torch\ndef f(g: torch.Generator) -> torch.Tensor: pass", False),
])
def test_the_rule_flags_what_it_should(snippet, flagged):
    assert bool(device_rule_violations(snippet + "\n", "snippet.py")) == flagged


@contextlib.contextmanager
def nothing_on_the_default_device():
    """Run the body with "meta" as the default device: a tensor made without an explicit
    device has no data there, and mixing it with CPU tensors or reading it raises."""
    previous = torch.get_default_device()
    torch.set_default_device("meta")
    try:
        yield
    finally:
        torch.set_default_device(None if previous.type == "cpu" else previous)


def _with_the_cpu_default(function):
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with torch.device("cpu"):
            return function(*args, **kwargs)

    return wrapper


@pytest.fixture
def others_on_the_cpu_default(monkeypatch):
    """Code outside the project that makes tensors on the default device gets the CPU default
    it has in use: in some torch versions (2.11 seen), the step counter of Adam's state (a CPU
    scalar torch reads with .item())."""
    monkeypatch.setattr(torch.optim.Adam, "_init_group",
                        _with_the_cpu_default(torch.optim.Adam._init_group))


def _all_on_the_cpu(module: torch.nn.Module) -> bool:
    return all(t.device.type == "cpu" for t in [*module.parameters(), *module.buffers()])


def test_the_training_pipeline_keeps_to_its_inputs_device(tmp_path, others_on_the_cpu_default):
    data = tiny_dataset()
    settings = tiny_train_settings(
        color=dict(iterations=12, growth_every=2, rate_start=0.25), semantic_iterations=4,
        stage3_iterations=3, checkpoint_every=6, encoder_fit=FitSettings(steps=4, batch=64))
    with nothing_on_the_default_device():
        result = train_scene(data.views, data.scene.positions, settings,
                             checkpoint_dir=tmp_path)
        resumed = load_checkpoint(tmp_path / CHECKPOINT_FILE)
        maps, _ = resumed.model.render(data.views[0].camera)
    state = result.color_state
    anchors = state.history["anchors"]
    assert anchors[-1] != anchors[0], "growth or pruning should have run"
    assert max(state.history["bits_per_parameter"]) > 0, "the rate term should have run"
    assert _all_on_the_cpu(state.model) and _all_on_the_cpu(state.rate_model)
    assert result.semantic is not None and np.isfinite(result.semantic.losses).all()
    assert len(result.data) > 0
    assert _all_on_the_cpu(resumed.model)
    assert maps.image.device.type == "cpu" and torch.isfinite(maps.image).all()


def test_rendering_and_its_gradients_keep_to_the_inputs_device():
    data = tiny_dataset()
    scene, camera = data.scene, data.views[0].camera
    tensors = {k: v.requires_grad_(True) for k, v in scene_tensors(scene).items()}
    features = torch.randn(len(scene), 4, generator=torch.Generator().manual_seed(0),
                           requires_grad=True)
    with nothing_on_the_default_device():
        out = rasterize_gaussians(**tensors, camera=camera, features=features,
                                  background=(0.1, 0.2, 0.3))
        (out.image.sum() + out.depth.sum() + out.features.sum()).backward()
        prepared = prepare_gaussians(tensors["means"], tensors["log_scales"], tensors["quats"],
                                     tensors["opacity_logits"], camera, sh=tensors["sh"])
        proj = prepared.projected
        order = depth_order(proj.depths, proj.visible)
        values = torch.cat([prepared.colors, proj.depths[:, None]], dim=1)
        # Small budgets: several bands, depth chunks, and the checkpointed backward pass.
        acc, _ = composite(order, proj.means2d, proj.conics, proj.opacities, proj.extents,
                           values, camera.width, camera.height, pair_budget=256,
                           checkpointed=True)
        acc.sum().backward()
        front_door = render(scene, camera, backend="torch", features=scene.sh_dc)
        jacobian = jacobian_sensitivity(scene.subset(np.arange(60)), [camera])
    for t in [*tensors.values(), features]:
        assert t.grad is not None and t.grad.device.type == "cpu"
        assert torch.isfinite(t.grad).all()
    assert np.isfinite(front_door.image).all() and front_door.features.shape[2] == 3
    assert all(np.isfinite(v).all() for v in jacobian.values.values())


def test_the_color_hyperprior_fit_keeps_to_the_cpu():
    rng = np.random.default_rng(4)
    cells = rng.integers(0, 1 << 10, (500, 3))
    residuals = np.column_stack([cells[:, 0] // 64 + rng.integers(-2, 3, 500),
                                 rng.integers(-5, 6, 500)])
    with nothing_on_the_default_device():
        fit = ColorPriorFit(cells, 10, residuals, ColorFitSettings(steps=10, batch=64),
                            mean_bits=MEAN_BITS, mean_limit=MEAN_LIMIT)
        fit.train(10)
        network = fit.export()
    assert _all_on_the_cpu(fit.net)
    assert network.forward(cells[:5]).shape == (5, 4)
