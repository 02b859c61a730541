"""The three CSGaussian training stages end to end: views + points -> a .csgs bitstream.

1. Stage 1 (:mod:`.color_stage`) fits anchors for rate and quality, checkpointing as it goes.
2. The anchors are encoded once (color only) to learn each anchor's color step q_f and the
   reconstruction a decoder will see.
3. Stage 2 fits per-anchor semantic features s to the views' instance masks on that
   reconstruction (:mod:`.semantic_stage`: quantization noise Q = 1, quality-aware weights
   from q_f, normalised over the range of steps the codec can give an anchor); stage 3
   continues with the rate of s under a hyperprior on the anchor positions. The built-in
   segmenter's over-segments are first made into objects consistent across views by the
   anchors' 3D structure (:mod:`.segment_objects`).
4. s, scaled from quantization steps to the encoder's semantic step, joins the anchors, and
   the scene is encoded with both layers.

Stage 1 checkpoints to ``checkpoint_dir/stage1.pt`` every ``checkpoint_every`` steps and at its
end; with ``resume`` a run continues from that file (stages 2-4 take seconds and are re-run).
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import nn

from csgs_codec.codec.anchor_encoder import AnchorEncoder, AnchorEncodeReport
from csgs_codec.decisions.presets import ANCHOR_BASE_STEPS, MULTIPLIERS
from csgs_codec.errors import CsgsWarning, InputError, ModelError
from csgs_codec.model.anchor_hyperprior import STEP_RANGE, FitSettings
from csgs_codec.model.scaffold import ScaffoldDecoder
from csgs_codec.scene.anchor_scene import AnchorScene, default_semantic_names
from csgs_codec.scene.cameras_io import resize_camera
from csgs_codec.train import defaults
from csgs_codec.train.anchor_rate import cell_embedding
from csgs_codec.train.checkpoint import load_checkpoint, save_checkpoint
from csgs_codec.train.color_stage import (
    ColorStageSettings,
    ColorStageState,
    StageProgress,
    initial_state,
    train_color_stage,
)
from csgs_codec.train.image_files import resize_mask
from csgs_codec.train.losses import CONTRASTIVE_MARGIN
from csgs_codec.train.segment_objects import object_masks
from csgs_codec.train.semantic_stage import (
    SEMANTIC_DIM,
    SemanticResult,
    SemanticView,
    contribution_matrix,
    train_semantic_features,
)
from csgs_codec.train.views import TrainingView

#: The anchor encoder's steps lie within this factor of the quality's base step.
STEP_FACTOR = 2.0 ** (STEP_RANGE / 8)
#: File name of the stage-1 checkpoint in the checkpoint folder.
CHECKPOINT_FILE = "stage1.pt"


@dataclass
class TrainSettings:
    """Settings of a whole run.

    Attributes:
        color: stage-1 settings (its ``quality`` is also the final encode's quality).
        semantic_iterations: stage-2 steps; stage3_iterations: stage-3 steps (0 skips it).
        feature_rate_weight: lambda_feature_rate of stage 3 (bits per anchor vs the stage-2
            loss).
        semantic_dim: width of s.
        contrastive_margin: margin of L_c in quantization steps of s (it sets how far apart
            the masks' mean features sit, so also the semantic layer's size).
        checkpoint_every: stage-1 steps between checkpoints (with a checkpoint folder).
        encoder_fit: the anchor encoder's hyperprior fitting settings (default its own).
        budget_seconds: wall seconds the whole run may take (None: ``color.iterations``
            steps): stage 1's length is then set from the speed of its first steps
            (:func:`budget_iterations`), so the file depends on the machine's speed.
    """

    color: ColorStageSettings = field(default_factory=ColorStageSettings)
    semantic_iterations: int = defaults.SEMANTIC_ITERATIONS
    stage3_iterations: int = 100
    feature_rate_weight: float = defaults.FEATURE_RATE_WEIGHT
    semantic_dim: int = SEMANTIC_DIM
    contrastive_margin: float = CONTRASTIVE_MARGIN
    checkpoint_every: int = 500
    encoder_fit: FitSettings | None = None
    budget_seconds: float | None = None


#: Stage-1 steps timed before a time budget sets the stage's length.
BUDGET_PROBE_STEPS = 40
#: Share of a time budget stage 1 plans for at its probe's speed: the rest is left for the
#: encodes and the semantic stages (15-20% on mary_rose at 384 px) and for the stage's own
#: slowdown as anchors grow and the rate term starts.
BUDGET_STAGE1_SHARE = 0.7
#: Most stage-1 steps a budget may plan.
BUDGET_MAX_ITERATIONS = 100_000


def budget_iterations(steps_per_second: float, seconds_left: float) -> int:
    """Stage-1 steps that fit a budget: ``BUDGET_STAGE1_SHARE`` of the ``seconds_left`` at
    ``steps_per_second``, at least one more than the probe's and at most
    :data:`BUDGET_MAX_ITERATIONS`."""
    planned = int(steps_per_second * max(seconds_left, 0.0) * BUDGET_STAGE1_SHARE)
    return min(max(planned, BUDGET_PROBE_STEPS + 1), BUDGET_MAX_ITERATIONS)


@dataclass
class TrainResult:
    """What :func:`train_scene` returns.

    Attributes:
        data: the .csgs bytes (color layer, and the semantic layer when the views had masks).
        encode: the final encode's report (``reconstruction`` is what a decoder returns).
        color_state: stage 1's final state (model, history).
        semantic: stage 3's (or stage 2's) result, None without masks.
        seconds: stage name -> wall seconds of this run.
    """

    data: bytes
    encode: AnchorEncodeReport
    color_state: ColorStageState
    semantic: SemanticResult | None
    seconds: dict[str, float]


class PositionalFeaturePrior(nn.Module):
    """Stage 3's rate model of s: an MLP on each anchor's cell embedding predicting a mean and
    sigma per channel (the "second hyperprior"), in quantization steps. Its parameters are
    made on the device of ``cells``."""

    def __init__(self, cells: torch.Tensor, dim: int, hidden: int = 32) -> None:
        super().__init__()
        device = cells.device
        self.register_buffer("embedding", cell_embedding(cells))
        self.net = nn.Sequential(nn.Linear(self.embedding.shape[1], hidden, device=device),
                                 nn.ReLU(), nn.Linear(hidden, 2 * dim, device=device))
        self.dim = dim

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean, sigma), each (G, D), for noisy features (G, D) (the input only sets the
        device and dtype: the prediction depends on positions alone)."""
        out = self.net(self.embedding.to(features.device, features.dtype))
        return out[:, :self.dim], torch.exp(out[:, self.dim:]) + 0.11


def train_scene(views: list[TrainingView], points: np.ndarray, settings: TrainSettings, *,
                checkpoint_dir: str | Path | None = None, resume: bool = False,
                progress: Callable[[str, StageProgress | None], None] | None = None
                ) -> TrainResult:
    """Run every stage (module notes) on ``views`` starting from ``points`` ((N, 3) world).

    Args:
        progress: called with (stage name, :class:`StageProgress` or None at stage starts).

    Raises:
        InputError: no views, ``resume`` without a checkpoint, or bad settings.
    """
    report = progress or (lambda stage, step: None)
    seconds: dict[str, float] = {}
    checkpoint = Path(checkpoint_dir) / CHECKPOINT_FILE if checkpoint_dir else None
    if checkpoint is not None:
        try:
            Path(checkpoint_dir).mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(f"cannot use as checkpoint folder: {error.strerror or error}",
                             file=checkpoint_dir) from None
    if resume:
        if checkpoint is None or not checkpoint.is_file():
            raise InputError("nothing to resume: no stage-1 checkpoint", file=checkpoint)
        state = load_checkpoint(checkpoint, device=settings.color.device)
        _check_resumable(state.settings, settings.color, checkpoint)
    else:
        state = initial_state(views, points, settings.color)
    report("stage 1: color", None)
    began = time.perf_counter()
    if settings.budget_seconds is not None and state.step == 0:
        # Time the first steps, then set the stage's length (its schedules are fractions
        # of it, and the probe ends before growth and the rate term start).
        probe = min(BUDGET_PROBE_STEPS, state.settings.iterations)
        train_color_stage(views, state, progress=lambda p: report("stage 1: color", p),
                          stop_at=probe)
        elapsed = time.perf_counter() - began
        state.settings = dataclasses.replace(state.settings, iterations=budget_iterations(
            probe / max(elapsed, 1e-9), settings.budget_seconds - elapsed))
    every = settings.checkpoint_every if checkpoint is not None else state.settings.iterations
    while state.step < state.settings.iterations:
        stop = min(state.step + max(every, 1), state.settings.iterations)
        train_color_stage(views, state, progress=lambda p: report("stage 1: color", p),
                          stop_at=stop)
        if checkpoint is not None:
            save_checkpoint(state, checkpoint)
    seconds["stage1"] = time.perf_counter() - began

    quality = state.settings.quality
    anchors = state.model.to_anchor_scene()
    if views:
        anchors.view_origins = np.stack([np.asarray(v.camera.position, np.float32)
                                         for v in views])
    if len(anchors) == 0:
        raise ModelError("stage 1 masked every Gaussian slot, leaving no anchor to encode: "
                         "train with a smaller rate weight (--lambda)", property="lambda")
    report("encoding the color layer", None)
    began = time.perf_counter()
    color = AnchorEncoder(quality, semantic="none",
                          fit=settings.encoder_fit).encode_with_report(anchors)
    seconds["color_encode"] = time.perf_counter() - began

    semantic = None
    with_masks = sum(v.mask is not None for v in views)
    if 0 < with_masks < len(views):
        warnings.warn(f"only {with_masks} of {len(views)} views have instance masks: the "
                      "semantic stages need every view's, so the file has no semantic layer",
                      CsgsWarning, stacklevel=2)
    if views and with_masks == len(views):
        report("stages 2-3: semantics", None)
        began = time.perf_counter()
        semantic = _semantic_stages(views, color, settings, report)
        seconds["stages2_3"] = time.perf_counter() - began
        step = ANCHOR_BASE_STEPS["semantic"] * MULTIPLIERS[quality]
        values = np.zeros((len(anchors), settings.semantic_dim), np.float32)
        values[color.order] = semantic.features * np.float32(step)
        anchors.semantic = values
        anchors.semantic_names = default_semantic_names(settings.semantic_dim)
    report("encoding the file", None)
    began = time.perf_counter()
    final = AnchorEncoder(quality, fit=settings.encoder_fit).encode_with_report(anchors)
    seconds["encode"] = time.perf_counter() - began
    return TrainResult(final.data, final, state, semantic, seconds)


#: Settings that may differ between a checkpoint and the run resuming it.
RESUMABLE_CHANGES = ("device", "threads")


def _check_resumable(saved: ColorStageSettings, asked: ColorStageSettings,
                     checkpoint: Path) -> None:
    """InputError naming the checkpoint when ``asked`` differs from the settings the
    checkpoint was trained with in anything but :data:`RESUMABLE_CHANGES`."""
    differ = [f"{name} {getattr(saved, name)!r} (asked {getattr(asked, name)!r})"
              for name in (f.name for f in dataclasses.fields(ColorStageSettings))
              if name not in RESUMABLE_CHANGES and getattr(saved, name) != getattr(asked, name)]
    if differ:
        raise InputError("the checkpoint was trained with other settings: "
                         + "; ".join(differ) + ". Resume with the same options, or start "
                         "again without --resume", file=checkpoint)


#: Longest image side the semantic stages see (larger views are downscaled for them, masks by
#: nearest neighbour): their contribution matrices grow with the pixels, and instance
#: features need no finer masks (mary_rose at 384 px: 12 GB and 11 minutes in stage 2).
SEMANTIC_MAX_SIDE = 160


def _semantic_view_size(width: int, height: int) -> tuple[int, int]:
    """(width, height) of a view for the semantic stages (:data:`SEMANTIC_MAX_SIDE`)."""
    side = max(width, height)
    if side <= SEMANTIC_MAX_SIDE:
        return width, height
    return (max(1, round(width * SEMANTIC_MAX_SIDE / side)),
            max(1, round(height * SEMANTIC_MAX_SIDE / side)))


def _semantic_stages(views: list[TrainingView], color: AnchorEncodeReport,
                     settings: TrainSettings, report: Callable) -> SemanticResult:
    threads = torch.get_num_threads()
    torch.set_num_threads(settings.color.threads)
    try:
        return _semantic_steps(views, color, settings, report)
    finally:
        torch.set_num_threads(threads)


def _semantic_steps(views: list[TrainingView], color: AnchorEncodeReport,
                    settings: TrainSettings, report: Callable) -> SemanticResult:
    scene: AnchorScene = color.reconstruction
    decoder = ScaffoldDecoder(scene)
    m = len(scene)
    prepared = []
    report("stages 2-3: preparing the views", None)
    for done, view in enumerate(views, 1):
        decoded = decoder.decode(view.camera.position)
        width, height = _semantic_view_size(view.camera.width, view.camera.height)
        camera, mask = view.camera, view.mask
        if (width, height) != (camera.width, camera.height):
            camera, mask = resize_camera(camera, width, height), resize_mask(mask, width, height)
        matrix = contribution_matrix(decoded.gaussians, camera, decoded.anchor_index,
                                     group_count=m)
        prepared.append(SemanticView(matrix, torch.as_tensor(mask.astype(np.int64),
                                                             device=matrix.device)))
        report("stages 2-3: preparing the views", _count(done, len(views), m))
    if all(view.oversegmented for view in views):
        merged = object_masks([v.contributions for v in prepared],
                              [v.mask.cpu().numpy() for v in prepared], scene.positions)
        prepared = [SemanticView(v.contributions, torch.as_tensor(
            mask.astype(np.int64), device=v.contributions.device))
            for v, mask in zip(prepared, merged)]

    def steps(stage: str, total: int) -> Callable[[int], None]:
        report(stage, None)
        return lambda i: report(stage, _count(i + 1, total, m))

    device = settings.color.device
    seed = settings.color.seed
    base = ANCHOR_BASE_STEPS["f"] * MULTIPLIERS[settings.color.quality]
    step_range = (base / STEP_FACTOR, base * STEP_FACTOR)
    result = train_semantic_features(prepared, m, color_steps=color.steps["f"],
                                     dim=settings.semantic_dim,
                                     iterations=settings.semantic_iterations, seed=seed,
                                     device=device, step_range=step_range,
                                     margin=settings.contrastive_margin,
                                     on_step=steps("stage 2: semantics",
                                                   settings.semantic_iterations))
    if settings.stage3_iterations > 0:
        cells = torch.as_tensor(np.rint((scene.positions - scene.positions.min(axis=0))
                                        / _voxel(scene)).astype(np.int64),
                                device="cpu")  # cpu: seeded prior weights equal on every device
        with torch.random.fork_rng(devices=[]):  # seeded weights, caller's RNG untouched
            torch.manual_seed(seed + 4)
            prior = PositionalFeaturePrior(cells, settings.semantic_dim)
        stage2_losses = result.losses
        result = train_semantic_features(
            prepared, m, color_steps=color.steps["f"], dim=settings.semantic_dim,
            iterations=settings.stage3_iterations, rate_weight=settings.feature_rate_weight,
            rate_model=prior, seed=seed + 1, device=device, initial_features=result.features,
            step_range=step_range, margin=settings.contrastive_margin,
            on_step=steps("stage 3: semantic rate", settings.stage3_iterations))
        result.losses = np.concatenate([stage2_losses, result.losses])
    return result


def _count(step: int, iterations: int, anchors: int) -> StageProgress:
    """Progress of a stage that reports no loss or PSNR (NaN)."""
    return StageProgress(step, iterations, float("nan"), float("nan"), 0.0, anchors)


def _voxel(scene: AnchorScene) -> float:
    """Smallest non-zero coordinate spacing of the anchors (their grid's cell), or 1."""
    spacings = []
    for axis in range(3):
        values = np.unique(scene.positions[:, axis].astype(np.float64))
        if len(values) > 1:
            spacings.append(float(np.diff(values).min()))
    return min(spacings) if spacings else 1.0
