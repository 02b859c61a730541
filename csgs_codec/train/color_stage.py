"""Stage 1: fit Scaffold-GS anchors to images for rate and quality (CSGaussian / HAC style).

Each step renders one training view (views in a seeded random order, every view once per
epoch) and minimises

    L = (1 - w) L1 + w (1 - SSIM)
        + lambda_rate * (R / P + lambda_mask * mean(sigmoid(mask logits)))
        [+ lambda_alpha * mean rendered opacity on the background, for views with a
           foreground mask (:mod:`.foreground`)]

where R is the estimated bits of the noisy features, offsets and scaling under
:class:`~csgs_codec.train.anchor_rate.AnchorRateModel` (trained jointly), P the number of coded
values (HAC's bits per parameter), and w = 0.2. For the first ``rate_start`` share of the steps
the anchors train without noise or rate (the MLPs first learn to render); after that every
render sees the attributes with uniform quantization noise of the encoder's steps at
``quality``, so the scene learns to survive the quantization it will get. Growing and pruning
(:mod:`.anchor_growth`) run every ``growth_every`` steps between ``growth_start`` and
``growth_end``. Gradients are clipped; a step whose loss is not finite is skipped and counted,
and many in a row stop the stage with a :class:`ModelError`. On the CPU with the seed fixed, the
same inputs give the same parameters bit for bit.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from csgs_codec.decisions.presets import ANCHOR_BASE_STEPS, ANCHOR_QUALITIES, MULTIPLIERS
from csgs_codec.errors import InputError, ModelError
from csgs_codec.metrics.image import psnr_from_mse
from csgs_codec.model.seeded_init import seeded_global_rng
from csgs_codec.render.differentiable import TRAINING_RASTERIZERS
from csgs_codec.train import defaults
from csgs_codec.train.anchor_growth import (
    GrowthStats,
    grow_and_prune,
    prune_mask,
    view_counts,
)
from csgs_codec.train.anchor_model import INIT_DEVICE, AnchorGrid, AnchorModel, grid_for_points
from csgs_codec.train.anchor_rate import AnchorRateModel
from csgs_codec.train.foreground import background_alpha_loss
from csgs_codec.train.grouped_adam import GroupedAdam, adam_step
from csgs_codec.train.losses import photometric_loss
from csgs_codec.train.quantization import add_quantization_noise
from csgs_codec.train.views import TrainingView

RATE_WEIGHT_PRESETS = defaults.RATE_WEIGHT_PRESETS

#: Parameter groups of ``ColorStageSettings.learning_rates``.
LEARNING_RATE_GROUPS = ("features", "offsets", "scaling", "mask_logits", "mlps", "rate")
#: Growth adds anchors on a grid this many halvings finer than the initial anchors'.
GROWTH_LEVELS = 1
#: Consecutive non-finite losses after which the stage gives up.
MAX_BAD_STEPS = 20


@dataclass
class ColorStageSettings:
    """Stage-1 settings (defaults suit small scenes on a CPU).

    Attributes:
        iterations: optimisation steps (one view each).
        rate_weight: lambda_rate (see :data:`RATE_WEIGHT_PRESETS`); 0 trains for quality only.
        mask_weight: lambda_mask, inside the rate term as in docs/design.md, 'Training'.
        quality: encoder quality whose steps the quantization noise uses (1..9).
        feat_dim: F; n_offsets: K.
        initial_anchors: anchors the initial points are voxelized into (about).
        max_anchors: growth stops here.
        min_views: anchors seen from fewer training views are pruned (view-frequency masking).
        rate_start: share of the steps before noise and rate start.
        growth_start, growth_end: share of the steps between which growth rounds run.
        growth_every: steps between growth rounds (0: every ``iterations // 10``).
        grow_fraction: share of seen slots (largest gradients) that may spawn anchors.
        min_opacity: anchors whose mean opacity per view stays below this are pruned.
        ssim_weight: w of the photometric loss.
        background_alpha_weight: lambda_alpha, the weight of the background opacity term of
            views with a foreground mask.
        learning_rates: parameter group -> initial Adam step size; MLPs and offsets decay
            exponentially to ``final_lr_ratio`` of it.
        final_lr_ratio: see ``learning_rates``.
        grad_clip: gradient norm limit per step.
        seed: seeds everything random (initial anchors, view order, noise).
        device: torch device ("cpu", "cuda").
        threads: torch CPU threads while training. One by default: the result then does not
            depend on the machine's core count (float sums keep their order), and small
            tensors gain nothing from more threads while a busy machine makes waiting threads
            spin (measured: 40 tiny steps took 39 s with 2 threads on a loaded 2-core machine,
            3.8 s with 1).
        background: RGB behind the scene, as in the training images.
        rasterizer: "auto" (gsplat on CUDA when installed, else the torch reference), "torch"
            or "gsplat" (see :mod:`csgs_codec.render.differentiable`).
        all_slots: render every anchor slot, hidden ones at opacity 0, instead of gathering
            the kept ones (see :func:`csgs_codec.model.scaffold.neural_gaussians`): the same
            step in fewer operators and no host synchronisation. None: with gsplat.
    """

    iterations: int = defaults.ITERATIONS
    rate_weight: float = defaults.RATE_WEIGHT_PRESETS[0]
    mask_weight: float = 0.25
    quality: int = defaults.QUALITY
    feat_dim: int = defaults.FEAT_DIM
    n_offsets: int = defaults.N_OFFSETS
    initial_anchors: int = defaults.INITIAL_ANCHORS
    max_anchors: int = defaults.MAX_ANCHORS
    min_views: int = 2
    rate_start: float = 0.3
    growth_start: float = 0.1
    growth_end: float = 0.6
    growth_every: int = 0
    grow_fraction: float = 0.05
    min_opacity: float = 0.005
    ssim_weight: float = 0.2
    background_alpha_weight: float = 0.2
    learning_rates: dict[str, float] = field(default_factory=lambda: {
        "features": 0.0075, "offsets": 0.01, "scaling": 0.007, "mask_logits": 0.01,
        "mlps": 0.004, "rate": 0.005})
    final_lr_ratio: float = 0.1
    grad_clip: float = 1.0
    seed: int = 0
    device: str = "cpu"
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    threads: int = defaults.THREADS
    rasterizer: str = "auto"
    all_slots: bool | None = None

    def validate(self) -> None:
        """Raise InputError naming the first setting out of range."""
        checks = [
            ("iterations", self.iterations >= 1),
            ("rate_weight", math.isfinite(self.rate_weight) and self.rate_weight >= 0),
            ("mask_weight", math.isfinite(self.mask_weight) and self.mask_weight >= 0),
            ("quality", self.quality in ANCHOR_QUALITIES),
            ("feat_dim", 1 <= self.feat_dim <= 256),
            ("n_offsets", 1 <= self.n_offsets <= 64),
            ("initial_anchors", self.initial_anchors >= 1),
            ("max_anchors", self.max_anchors >= 1),
            ("min_views", self.min_views >= 0),
            ("rate_start", 0.0 <= self.rate_start <= 1.0),
            ("grow_fraction", 0.0 <= self.grow_fraction <= 1.0),
            ("grad_clip", self.grad_clip > 0),
            ("threads", 1 <= self.threads <= 256),
            ("growth_start", 0.0 <= self.growth_start <= 1.0),
            ("growth_end", self.growth_start <= self.growth_end <= 1.0),
            ("growth_every", self.growth_every >= 0),
            ("min_opacity", 0.0 <= self.min_opacity < 1.0),
            ("ssim_weight", 0.0 <= self.ssim_weight <= 1.0),
            ("background_alpha_weight", math.isfinite(self.background_alpha_weight)
             and self.background_alpha_weight >= 0),
            ("final_lr_ratio", 0.0 < self.final_lr_ratio <= 1.0),
            ("seed", 0 <= self.seed < 2**63),
            ("device", self.device in ("cpu", "cuda") or self.device.startswith("cuda:")),
            ("rasterizer", self.rasterizer in TRAINING_RASTERIZERS),
            ("all_slots", self.all_slots in (None, True, False)),
            ("learning_rates", set(self.learning_rates) == set(LEARNING_RATE_GROUPS)
             and all(math.isfinite(v) and v > 0 for v in self.learning_rates.values())),
        ]
        for name, ok in checks:
            if not ok:
                raise InputError(f"{name} = {getattr(self, name)!r} is out of range",
                                 property=name)

    def steps(self) -> dict[str, float]:
        """Quantization step per attribute at ``quality`` (the encoder's base steps)."""
        scale = MULTIPLIERS[self.quality]
        base = ANCHOR_BASE_STEPS
        return {"features": base["f"] * scale, "offsets": base["offsets"] * scale,
                "scaling": base["scaling"] * scale}


@dataclass
class StageProgress:
    """What the progress callback receives after each step.

    Attributes:
        step: steps done; iterations: steps in the stage.
        loss: the step's total loss (photometric + weighted rate terms).
        psnr: PSNR of the step's render against its training image, dB.
        bits_per_parameter: the rate estimate, bits per coded value (0 before the rate
            term starts).
        anchors: anchors M after the step.
    """

    step: int
    iterations: int
    loss: float
    psnr: float
    bits_per_parameter: float
    anchors: int


def _order_generator() -> torch.Generator:
    """A generator for the view order: on the CPU, so the order is the same on every device
    and a checkpoint's generator state resumes on any."""
    return torch.Generator(device="cpu")  # cpu: the view order is the same on every device


@dataclass
class ColorStageState:
    """Everything stage 1 needs to continue: the model, its rate model, optimisers, the
    random generators and the step reached (checkpoints save and restore this). The noise
    generator must live on the training device (:func:`initial_state` puts it there)."""

    model: AnchorModel
    rate_model: AnchorRateModel
    settings: ColorStageSettings
    step: int = 0
    anchor_optimizer: GroupedAdam | None = None
    shared_optimizer: GroupedAdam | None = None
    view_generator: torch.Generator = field(default_factory=_order_generator)
    noise_generator: torch.Generator = field(default_factory=_order_generator)
    order: list[int] = field(default_factory=list)
    stats: GrowthStats | None = None
    history: dict[str, list[float]] = field(default_factory=lambda: {
        "loss": [], "psnr": [], "bits_per_parameter": [], "anchors": []})
    skipped_steps: int = 0
    bad_run: int = 0
    seconds: float = 0.0
    view_names: list[str] = field(default_factory=list)


def initial_state(views: list[TrainingView], points: np.ndarray,
                  settings: ColorStageSettings) -> ColorStageState:
    """Anchors from ``points`` ((N, 3) world units) voxelized to about
    ``settings.initial_anchors`` cells, minus those seen by fewer than ``min_views`` views."""
    settings.validate()
    if not views:
        raise InputError("stage 1 needs at least one training view", property="views")
    for view in views:
        view.validate()
    coarse = grid_for_points(points, settings.initial_anchors)
    cells = np.unique(coarse.cells_of(points), axis=0)
    min_views = min(settings.min_views, len(views))
    seen = view_counts(coarse.centres(cells), [v.camera for v in views]) >= min_views
    if not seen.any():
        raise InputError(f"no initial anchor is seen by {min_views} training views: the "
                         "points and cameras do not overlap", property="points")
    refine = 2 ** GROWTH_LEVELS
    grid = AnchorGrid(coarse.origin, coarse.voxel / refine)
    model = AnchorModel(cells[seen] * refine, grid, feat_dim=settings.feat_dim,
                        n_offsets=settings.n_offsets, seed=settings.seed,
                        initial_log_scale=math.log(coarse.voxel), device=settings.device)
    with seeded_global_rng(settings.seed + 3):  # seeded initial weights, caller's untouched
        # Drawn on INIT_DEVICE, then moved: the same initial weights on every device.
        rate_model = AnchorRateModel(settings.feat_dim, settings.n_offsets, settings.steps(),
                                     device=INIT_DEVICE)
    state = ColorStageState(model, rate_model.to(settings.device), settings)
    state.view_names = [view.name for view in views]
    state.view_generator.manual_seed(settings.seed + 1)
    state.noise_generator = torch.Generator(device=settings.device).manual_seed(
        settings.seed + 2)
    make_optimizers(state)
    return state


def make_optimizers(state: ColorStageState, keep_shared: bool = False) -> None:
    """(Re)build the Adam optimisers: one over the per-anchor tensors (rebuilt after growth
    changes their shapes) and one over the MLPs and the rate model (kept if ``keep_shared``)."""
    lrs = state.settings.learning_rates
    model = state.model
    # GroupedAdam: one update pass over every group of both optimisers (adam_step), not one
    # per group; on a GPU the step is bound by such calls. Same rule as torch's Adam.
    state.anchor_optimizer = GroupedAdam(
        [{"params": [t], "lr": lrs[name], "name": name}
         for name, t in model.anchor_tensors().items()], eps=1e-15)
    if not keep_shared or state.shared_optimizer is None:
        state.shared_optimizer = GroupedAdam(
            [{"params": list(model.mlps.parameters()), "lr": lrs["mlps"], "name": "mlps"},
             {"params": list(state.rate_model.parameters()), "lr": lrs["rate"],
              "name": "rate"}], eps=1e-15)


def _resize_anchor_optimizer(state: ColorStageState, old: dict[str, torch.Tensor],
                             keep: torch.Tensor) -> None:
    """After growth or pruning, a new per-anchor optimiser whose Adam moments are the old
    ones of the surviving rows (zeros for new rows), with the step count kept, as Scaffold-GS
    does; ``old`` holds the parameters before the round, ``keep`` (M_old,) the survivors."""
    previous = state.anchor_optimizer
    make_optimizers(state, keep_shared=True)
    for name, tensor in state.model.anchor_tensors().items():
        before = previous.state.get(old[name])
        if not before:
            continue
        rows = keep.to(tensor.device)
        added = tensor.shape[0] - int(rows.sum())
        moved = {}
        for key, value in before.items():
            if key in ("exp_avg", "exp_avg_sq"):
                moved[key] = torch.cat([value[rows],
                                        value.new_zeros((added,) + value.shape[1:])])
            else:
                moved[key] = value
        state.anchor_optimizer.state[tensor] = moved


def _set_learning_rates(state: ColorStageState) -> None:
    s = state.settings
    decay = s.final_lr_ratio ** (state.step / max(s.iterations - 1, 1))
    for optimizer in (state.anchor_optimizer, state.shared_optimizer):
        for group in optimizer.param_groups:
            base = s.learning_rates[group["name"]]
            group["lr"] = base * decay if group["name"] in ("offsets", "mlps") else base


def _next_view(state: ColorStageState, count: int) -> int:
    if not state.order:
        generator = state.view_generator
        state.order = torch.randperm(count, generator=generator,
                                     device=generator.device).tolist()
    return state.order.pop()


def _growth_window(settings: ColorStageSettings) -> tuple[int, int, int]:
    """(start, end, every): growth rounds run after steps t with start < t <= end and
    t % every == 0."""
    every = settings.growth_every or max(settings.iterations // 10, 1)
    return (int(settings.growth_start * settings.iterations),
            int(settings.growth_end * settings.iterations), every)


def _growth_due(state: ColorStageState) -> bool:
    start, end, every = _growth_window(state.settings)
    return start < state.step <= end and state.step % every == 0


def _growth_ahead(state: ColorStageState) -> bool:
    """Whether a growth round follows the step ``state.step`` is about to count (after the
    last round the growth statistics are not needed, and gathering them costs a step
    several copies to the CPU)."""
    start, end, every = _growth_window(state.settings)
    last = end - end % every
    return last > start and state.step + 1 <= last


def train_color_stage(views: list[TrainingView], state: ColorStageState, *,
                      progress: Callable[[StageProgress], None] | None = None,
                      stop_at: int | None = None) -> ColorStageState:
    """Run stage 1 from ``state.step`` to ``settings.iterations`` (or ``stop_at``) with
    ``settings.threads`` torch threads (restored afterwards).

    Args:
        views: the training views (the same list, in the same order, on every resume).
        state: from :func:`initial_state` or a checkpoint; updated in place and returned.
        progress: called after every step.
        stop_at: stop after this step (to checkpoint), default the last.

    Raises:
        ModelError: :data:`MAX_BAD_STEPS` consecutive steps had a non-finite loss.
    """
    threads = torch.get_num_threads()
    torch.set_num_threads(state.settings.threads)
    try:
        return _train_steps(views, state, progress, stop_at)
    finally:
        torch.set_num_threads(threads)


def _train_steps(views: list[TrainingView], state: ColorStageState,
                 progress: Callable[[StageProgress], None] | None,
                 stop_at: int | None) -> ColorStageState:
    s = state.settings
    names = [view.name for view in views]
    if state.view_names and names != state.view_names:
        raise InputError(f"these {len(names)} views are not the {len(state.view_names)} "
                         "views this stage-1 state was trained on (a checkpoint resumes only "
                         "with the same dataset and options)", property="views")
    device = torch.device(s.device)
    targets = [torch.as_tensor(v.image, device=device) for v in views]
    backgrounds = [None if v.foreground is None else torch.as_tensor(~v.foreground, device=device)
                   for v in views]
    seen_cache: dict[int, np.ndarray] = {}
    began = time.perf_counter()
    end = s.iterations if stop_at is None else min(stop_at, s.iterations)
    model, rate_model = state.model, state.rate_model
    steps = s.steps()
    if state.stats is None:
        state.stats = GrowthStats.empty(model.count, model.n_offsets)
    cameras = [view.camera for view in views]
    min_views = min(s.min_views, len(views))

    def seen_enough(centres: np.ndarray) -> np.ndarray:
        return view_counts(centres, cameras) >= min_views

    while state.step < end:
        index = _next_view(state, len(views))
        camera = views[index].camera
        _set_learning_rates(state)
        state.anchor_optimizer.zero_grad(set_to_none=True)
        state.shared_optimizer.zero_grad(set_to_none=True)
        with_rate = state.step >= int(s.rate_start * s.iterations)
        noisy = None
        if with_rate:
            noisy = {name: add_quantization_noise(getattr(model, name), steps[name],
                                                  generator=state.noise_generator)
                     for name in steps}
        probabilities = torch.sigmoid(model.mask_logits)
        mask = model.mask(probabilities)
        out, gaussians = model.render(camera, noisy, s.background, s.rasterizer, mask=mask,
                                      all_slots=s.all_slots)
        record = _growth_ahead(state)
        if record:
            gaussians.positions.retain_grad()
        loss = photometric_loss(out.image, targets[index], s.ssim_weight)
        if backgrounds[index] is not None and s.background_alpha_weight > 0:
            loss = loss + s.background_alpha_weight * background_alpha_loss(
                out.alpha, backgrounds[index])
        bits_per_parameter = None
        if with_rate and s.rate_weight > 0:
            estimate = rate_model.estimate(model.cells, noisy, mask)
            loss = loss + s.rate_weight * (estimate.bits_per_parameter
                                           + s.mask_weight * probabilities.mean())
            bits_per_parameter = estimate.bits_per_parameter.detach()
        if not loss.requires_grad:  # the view sees no Gaussian: nothing to learn from it
            state.step += 1
            continue
        loss.backward()
        parameters = [p for g in state.anchor_optimizer.param_groups for p in g["params"]]
        parameters += [p for g in state.shared_optimizer.param_groups for p in g["params"]]
        norm = torch.nn.utils.clip_grad_norm_(parameters, s.grad_clip)
        with torch.no_grad():  # on the device: the step's scalars cross to the host in one copy
            error = (out.image.detach().clamp(0, 1) - targets[index]).square().mean()
            scalars = [loss.detach(), norm.to(loss.dtype), error]
            if bits_per_parameter is not None:
                scalars.append(bits_per_parameter.to(loss.dtype))
            scalars = torch.stack(scalars).double().tolist()
        loss_value, norm_value, mse = scalars[:3]
        bits_per_parameter = scalars[3] if len(scalars) > 3 else 0.0
        if not (math.isfinite(loss_value) and math.isfinite(norm_value)):
            # Skip the step: nothing is applied (the gradients are dropped next step).
            state.bad_run += 1
            state.skipped_steps += 1
            if state.bad_run >= MAX_BAD_STEPS:
                raise ModelError(f"stage 1 diverged: {state.bad_run} consecutive steps with a "
                                 f"non-finite loss or gradient at step {state.step}",
                                 property="loss")
            state.step += 1
            continue
        state.bad_run = 0
        adam_step(state.anchor_optimizer, state.shared_optimizer)
        if record:
            if index not in seen_cache:
                seen_cache[index] = view_counts(model.positions.cpu().numpy(), [camera]) > 0
            state.stats.record(gaussians, camera, model.n_offsets, seen_cache[index])
        state.step += 1
        quality = psnr_from_mse(mse)
        for key, value in (("loss", loss_value), ("psnr", quality),
                           ("bits_per_parameter", bits_per_parameter),
                           ("anchors", float(model.count))):
            state.history[key].append(value)
        if _growth_due(state):
            keep = ~prune_mask(state.stats, s.min_opacity)
            old = dict(model.anchor_tensors())
            grown, pruned = grow_and_prune(
                model, state.stats, grow_fraction=s.grow_fraction, min_opacity=s.min_opacity,
                max_anchors=s.max_anchors, accept=seen_enough)
            if grown or pruned:
                _resize_anchor_optimizer(state, old, keep)
                seen_cache.clear()
            state.stats = GrowthStats.empty(model.count, model.n_offsets)
        if progress is not None:
            progress(StageProgress(state.step, s.iterations, loss_value, quality,
                                   bits_per_parameter, model.count))
    state.seconds += time.perf_counter() - began
    return state
