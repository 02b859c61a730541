"""Semantics for any standard 3DGS scene: stages 2-3 on its fixed Gaussians, from the capture's
images, cameras and instance masks.

1. One pass of the reference compositor per view gives the linear map from per-Gaussian
   features to the view's rendered feature map (:func:`contribution_matrix`; cost one render
   whatever the scene's size), and all views become one sparse product
   (:class:`~csgs_codec.train.semantic_batch.ViewBatch`).
2. Stage 2 trains a D-channel feature per Gaussian with the intra-mask smoothing and
   inter-mask contrastive losses under quantization noise
   (:func:`~csgs_codec.train.semantic_stage.train_semantic_features`).
   Views whose masks are the built-in segmenter's over-segments (every view's
   ``oversegmented``) first have them made into objects consistent across views
   (:func:`~csgs_codec.train.segment_objects.object_masks`).
3. The features pick instances: masks of different views that show one object are joined by
   their features, each Gaussian takes the nearest object and then the majority of its 3D
   neighbours (:func:`~csgs_codec.train.instances.lift_instances`).
4. Stage 3 for a standard scene is the codec's own semantic coding: every Gaussian's feature
   becomes its instance's prototype (rounded to binary16), so the features are K distinct rows
   that the encoder codes exactly as a codebook (``SEMC``, FORMAT §12.23) at a fraction of a
   bit per Gaussian, and selection by instance (``csgs select --mode instance``) is the same
   before and after coding. No quantization step to apply by hand: the prototypes are written
   as they are.

The features are written as ``ins_feat_0``.. (the per-Gaussian layout OpenGaussian uses), in
feature units of stage 2 (masks' mean features trained at least ``margin`` apart).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from csgs_codec.errors import InputError, require_type
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.scene.instance_table import MAX_EMBEDDING_DIM, InstanceTable
from csgs_codec.train import defaults
from csgs_codec.train.heap import release_freed_memory
from csgs_codec.train.instances import NEIGHBOURS, Instances, lift_instances
from csgs_codec.train.segment_objects import object_masks
from csgs_codec.train.semantic_batch import ViewBatch
from csgs_codec.train.semantic_stage import (
    SEMANTIC_DIM,
    contribution_matrix,
    train_semantic_features,
)
from csgs_codec.train.views import TrainingView

#: Feature channel names written by :func:`segment_scene` (channel i is ``ins_feat_i``).
FEATURE_PREFIX = "ins_feat_"
#: Most stage-2 steps (the default is 150; a million already takes days).
MAX_ITERATIONS = 1_000_000
#: Largest contrastive margin, feature units (the default is 4: features a margin of 1e300
#: apart overflow float32).
MAX_MARGIN = 1000.0


@dataclass(frozen=True)
class SegmentSettings:
    """How :func:`segment_scene` trains.

    Attributes:
        iterations: stage-2 Adam steps, each over every view.
        dim: feature channels D.
        margin: contrastive margin between masks' mean features (feature units).
        learning_rate: Adam step size.
        neighbours: 3D neighbours voting for each Gaussian's instance (1: none).
        seed: seeds the initial features and the noise.
        device: torch device for the compositing and the training.
        ignore_id: mask id of pixels that belong to no instance, or None.
    """

    iterations: int = defaults.SEMANTIC_ITERATIONS
    dim: int = SEMANTIC_DIM
    margin: float = defaults.CONTRASTIVE_MARGIN
    learning_rate: float = 0.1
    neighbours: int = NEIGHBOURS
    seed: int = 0
    device: str = "cpu"
    ignore_id: int | None = None

    def validate(self) -> None:
        """Raises InputError naming the first setting out of range."""
        for name, low in (("iterations", 1), ("dim", 1), ("neighbours", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise InputError(f"{name} must be an integer >= {low}, got {value!r}",
                                 property=name)
        if self.dim > 255:
            raise InputError(f"dim must be at most 255 channels, got {self.dim}",
                             property="dim")
        if self.iterations > MAX_ITERATIONS:
            raise InputError(f"iterations must be at most {MAX_ITERATIONS:,}, got "
                             f"{self.iterations:,}", property="iterations")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) \
                or not 0 <= self.seed < 2**63:
            raise InputError(f"seed must be an integer in 0..2^63-1, got {self.seed!r}",
                             property="seed")
        if isinstance(self.margin, int | float) and self.margin > MAX_MARGIN:
            raise InputError(f"margin must be at most {MAX_MARGIN:g}, got {self.margin!r}",
                             property="margin")
        for name in ("margin", "learning_rate"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a finite number > 0, got {value!r}",
                                 property=name)


@dataclass
class SegmentResult:
    """What :func:`segment_scene` returns.

    Attributes:
        scene: the input scene with ``semantic`` (N, D) float32 = each Gaussian's instance
            prototype, named ``ins_feat_0``..; labels left as they were.
        instances: the instances (ids, prototypes, counts, visibility).
        losses: (iterations,) stage-2 loss per step.
        seconds: wall seconds per phase ("render", "stage2", "instances").
    """

    scene: GaussianScene
    instances: Instances
    losses: np.ndarray
    seconds: dict[str, float] = field(default_factory=dict)


def segment_scene(scene: GaussianScene, views: list[TrainingView],
                  settings: SegmentSettings = SegmentSettings(), *,
                  mask_embeddings: list[np.ndarray | None] | None = None,
                  progress: Callable[[str, int, int], None] | None = None) -> SegmentResult:
    """Give every Gaussian of ``scene`` an instance and its prototype feature (module notes).

    Args:
        scene: the fixed Gaussians, in the cameras' world frame.
        views: views of the capture, each with a camera and an instance mask (image pixels are
            not used).
        settings: :class:`SegmentSettings`.
        mask_embeddings: per view, an (I, E) array whose row i embeds the view's mask id i
            (an image embedding of the mask's pixels, say; rows of ids absent from the view
            are ignored), or None for a view without; gives the result an instance table
            (:func:`instance_embeddings`) for open-vocabulary queries.
        progress: called as ``progress(phase, done, total)`` while rendering views ("render")
            and training ("stage2").

    Returns:
        :class:`SegmentResult`.

    Raises:
        InputError: an empty scene, no views, a view without a mask or whose mask does not
            match its camera, bad settings, or masks that cover no Gaussian.
    """
    settings.validate()
    if not isinstance(scene, GaussianScene) or len(scene) == 0:
        raise InputError("segmenting needs a standard scene with at least one Gaussian",
                         property="scene")
    if not isinstance(views, list | tuple) or not views:
        raise InputError("segmenting needs a list of at least one view with a mask",
                         property="views")
    for view in views:
        require_type(view, TrainingView, "views")
    report = progress or (lambda phase, done, total: None)
    seconds = {}
    began = time.perf_counter()
    contributions, masks = [], []
    for i, view in enumerate(views):
        if view.mask is None:
            raise InputError("every view needs an instance mask", file=view.name or None,
                             index=i, property="mask")
        if view.mask.shape != (view.camera.height, view.camera.width):
            raise InputError(f"mask is {view.mask.shape[1]}x{view.mask.shape[0]} but its "
                             f"camera is {view.camera.width}x{view.camera.height}",
                             file=view.name or None, index=i, property="mask")
        contributions.append(contribution_matrix(scene, view.camera, device=settings.device))
        masks.append(view.mask)
        report("render", i + 1, len(views))
    seconds["render"] = time.perf_counter() - began
    if all(view.oversegmented for view in views):
        began = time.perf_counter()
        masks = object_masks(contributions, masks, scene.positions)
        seconds["objects"] = time.perf_counter() - began
        release_freed_memory()
    began = time.perf_counter()
    # The batch takes each view's matrix over as it reads it (release): the peak memory
    # holds the contributions once.
    batch = ViewBatch.from_views(
        contributions, [torch.as_tensor(mask.astype(np.int64), device=settings.device)
                        for mask in masks], len(scene),
        ignore_id=settings.ignore_id, device=settings.device, release=True)
    del contributions
    release_freed_memory()
    trained = train_semantic_features(
        [], len(scene), dim=settings.dim, iterations=settings.iterations,
        learning_rate=settings.learning_rate, margin=settings.margin,
        ignore_id=settings.ignore_id, seed=settings.seed, device=settings.device,
        on_step=lambda step: report("stage2", step + 1, settings.iterations), batch=batch)
    seconds["stage2"] = time.perf_counter() - began
    began = time.perf_counter()
    instances = lift_instances(batch, trained.features, scene.positions,
                               join_distance=settings.margin / 2,
                               neighbours=settings.neighbours)
    seconds["instances"] = time.perf_counter() - began
    names = tuple(f"{FEATURE_PREFIX}{i}" for i in range(settings.dim))
    # Prototypes rounded to binary16 (distinct ones stay margin-far apart), so the codebook
    # stores them in 2 bytes a value, exactly (FORMAT §12.23).
    prototypes = instances.prototypes.astype(np.float16).astype(np.float32)
    table = None
    if mask_embeddings is not None:
        table = InstanceTable(prototypes, instance_embeddings(batch, instances,
                                                              mask_embeddings))
    segmented = dataclasses.replace(scene, semantic=prototypes[instances.ids],
                                    semantic_names=names, instances=table)
    return SegmentResult(segmented, instances, trained.losses, seconds)


def instance_embeddings(batch: ViewBatch, instances: Instances,
                        mask_embeddings: list[np.ndarray | None]) -> np.ndarray:
    """(K, E) float32 unit embedding of each instance: the pixel-weighted mean of the unit
    embeddings of the masks joined into its object (zero where none has one).

    Raises:
        InputError: not one entry per view, arrays that are not (I, E) finite, widths that
            differ, or a mask id beyond its view's array.
    """
    views = batch.view_count
    if len(mask_embeddings) != views:
        raise InputError(f"{len(mask_embeddings)} mask embedding arrays for {views} views",
                         property="mask_embeddings")
    width = None
    for v, array in enumerate(mask_embeddings):
        if array is None:
            continue
        array = np.asarray(array)
        if array.ndim != 2 or not np.isfinite(array).all() or not \
                1 <= array.shape[1] <= MAX_EMBEDDING_DIM:
            raise InputError(f"view {v}: mask embeddings must be finite (I, E) with E in "
                             f"1..{MAX_EMBEDDING_DIM}, got {array.shape}", index=v,
                             property="mask_embeddings")
        if width not in (None, array.shape[1]):
            raise InputError(f"view {v}: embeddings of {array.shape[1]} values, earlier "
                             f"views {width}", index=v, property="mask_embeddings")
        width = array.shape[1]
    if width is None:
        raise InputError("no view has mask embeddings", property="mask_embeddings")
    sums = np.zeros((instances.objects, width))
    views_of = batch.mask_view.cpu().numpy()
    ids = batch.mask_ids.cpu().numpy()
    sizes = batch.sizes.double().cpu().numpy()
    for m, obj in enumerate(instances.mask_objects):
        array = mask_embeddings[views_of[m]]
        if obj < 0 or array is None:
            continue
        if not 0 <= ids[m] < len(array):
            raise InputError(f"view {views_of[m]}: mask id {ids[m]} has no embedding row "
                             f"(the array has {len(array)})", index=int(views_of[m]),
                             property="mask_embeddings")
        row = np.asarray(array[ids[m]], np.float64)
        norm = np.linalg.norm(row)
        if norm > 0:
            sums[obj] += sizes[m] * row / norm
    chosen = sums[instances.instance_objects]
    norms = np.linalg.norm(chosen, axis=1, keepdims=True)
    return np.where(norms > 0, chosen / np.where(norms > 0, norms, 1.0), 0.0).astype(np.float32)
