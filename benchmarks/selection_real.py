"""Click selection on a real scene with real per-Gaussian labels (issue #30, "Measure").

The baseline later sessions improve against. Nothing here changes the library: the scene's
Gaussians stay fixed and only the library's own semantic stage, codec and click selection run.

Scene and labels. ``../shared/data/real_sh3/fruit_drops.ply``: 4,721 real trained Gaussians,
SH degree 3, the words "MIXED DROPS" standing on a card, thin in z (the orbit's up axis).
``fruit_drops_labels.json`` is a segments.ai point-cloud segmentation export: the labels sit at
``dataset.samples[0].labels["ground-truth"].attributes.point_annotations``, one float per
Gaussian in file order (4,721 of them, all whole numbers); ``annotations`` and
``dataset.task_attributes.categories`` list 9 categories (ids 1-9, named "Category 1".."9")
of which 8 are used (1-8: 266-1,038 Gaussians each, letters of the text; a category can hold
several letters); 0 means unlabelled (229 Gaussians: the large, more opaque Gaussians of the
card).

Views. ``orbit_cameras(scene, 32, width=320, height=240)`` (up guessed, +z here; elevation 20
degrees); views 0, 4, 8, ... are held out (8), the other 24 train (as ``split_views(views, 4)``).

Ground truth. Each view's instance mask is ``csgs_codec.train.synthetic.instance_mask`` of the
labelled scene: per pixel the class with the largest rendered weight, or 0 where the final
transmittance is larger. Its classes are 1..K for the K categories and K + 1 for the unlabelled
Gaussians, so the card is an instance of its own in training (as a segmenter would give it)
but is never clicked.

Features. ``prepare_semantic_views`` (one contribution matrix per training view, one group per
Gaussian) and ``train_semantic_features`` with the pipeline's defaults (csgs_codec/train/
pipeline.py, TrainSettings): stage 2 for ``SEMANTIC_ITERATIONS`` steps (150), D = 6, margin 4,
seed 0, every Gaussian weighted 1 (fixed Gaussians have no stage-1 color step); stage 3
continues from stage 2's features for 100 steps with ``rate_weight`` = FEATURE_RATE_WEIGHT
(1.0) and seed 1. The pipeline's stage-3 rate model (PositionalFeaturePrior) needs anchor grid
cells; for standalone Gaussians the API's default model runs, a FactorizedGaussianPrior (one
learned Gaussian per channel).

Scaling. The stages return s in quantization steps: training adds U(-1/2, 1/2) noise, the
proxy of rounding s to integers (Q = 1). The codec quantizes a semantic value v with the
preset's step D_q = ``PRESETS[q].semantic_step`` (1/16, 1/32, 1/96 at qualities 3, 5, 8). The
scene is therefore given v = s * D_q, so that the integers coded, round(v / D_q) = round(s),
are the ones the noise proxy and the stage-3 rate model trained for (pipeline.py does the
same for anchors with ``ANCHOR_BASE_STEPS["semantic"]``). Unscaled, s would be coded 32 times
finer than trained at quality 5, five bits a channel more for nothing. Cosine selection does
not see the scale, so the uncompressed rows use s as trained; the coded rows differ from them
by the rounding of s (and the lossy geometry), the same integers at every quality.

Variants. ``segment``: ``csgs segment``'s library call (``segment_scene``) on the training
views and masks: stage 2 for the same steps, instances lifted from the features and masks, each
Gaussian's feature its instance's prototype, coded as they are (the encoder writes them exactly
as a codebook, SEMC) and clicked in "instance" mode (the instance carrying the most rendered
weight under the click). ``stage2`` and ``stage2+3`` (trained features, labels left out of the
file so they cannot leak); ``onehot``: the labels as features, one channel per class 0..K
(scaled the same way, channel value 1 = one step); ``labels``: the labels coded directly (the
semantic layer's label chunk), selected by "label under click": the label with the largest
rendered weight at the clicked pixel, all Gaussians with that label selected, and by the
library's "instance" mode, which reads labels as instances (the same rule, computed at the
clicked pixel only). Each variant is clicked uncompressed and after ``Encoder(quality=q)`` at
qualities 3, 5 and 8, decoded with ``layers="color,semantic"``; bytes come from
``describe_bitstream``.

Clicks. In every held-out view, for every category visible in its ground-truth mask (at least
``--min-pixels`` pixels), the mask pixel nearest the mask's centroid is clicked (pixel
centre), and ``click_selection`` runs in "cosine" (threshold 0.9) and "cluster" mode.

* 3D IoU: the selected Gaussians against the category's Gaussians (labels).
* 2D IoU, occlusion-aware: the selection becomes a class of its own in the rendered argmax.
  Every Gaussian of the scene clicked (decoded geometry for coded rows) gets one-hot
  features over [selected, class 1, ..., class K + 1] (unselected Gaussians keep their
  label's class), and a pixel shows the selection where the selected Gaussians' rendered
  weight beats both the final transmittance and every other class: the rule that made the
  ground-truth masks, so the labels themselves score 1.0 uncompressed. That mask is
  compared with the category's ground-truth mask in the view. Selected Gaussians hidden
  behind others cost nothing in 2D; they do in 3D.

A click whose pixel has no feature (accumulated opacity under 0.05, or an all-zero feature
under it) selects nothing and scores 0 in both. mIoU is the mean over all clicks.

Diagnostics beside the scores: per trained variant the feature norms (in steps), the norm
of the mean feature and the median distance to it, the share of features that round to all
zero (never selectable), how tightly each category's features point one way and the largest
cosine between two categories' directions; per coded row the share of all-zero decoded
features; the stage-3 prior's learned mean and sigma; and for the clicked pixels how much of
their rendered weight the clicked category carries (translucent objects mix classes in a
pixel, which no per-Gaussian feature can undo for a cosine threshold).

``--noisy-masks`` adds a run whose training masks have noisy boundaries (every pixel takes
the id of a pixel up to 2 px away, offsets uniform in -2..2 per axis, so only pixels near a
boundary change); ``--merged`` one where in 20% of the training views two visible categories
share a mask. Held-out ground truth stays clean. Stage times (wall seconds) and the machine
are recorded; ``notes`` says what was reduced to fit the time available.

Usage: .venv/bin/python benchmarks/selection_real.py [--out FILE] [--views 32]
    [--stage2-iterations 150] [--stage3-iterations 100] [--qualities 3 5 8]
    [--noisy-masks] [--merged] [--notes TEXT]
Writes one JSON document in the csgs-bench/1 schema (see benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import REPO, document, emit  # noqa: E402

from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.describe import describe_bitstream  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import PRESETS  # noqa: E402
from csgs_codec.errors import InputError  # noqa: E402
from csgs_codec.scene.gaussian_scene import GaussianScene  # noqa: E402
from csgs_codec.scene.orbit import orbit_cameras  # noqa: E402
from csgs_codec.semantic.clustering import unit_rows  # noqa: E402
from csgs_codec.semantic.evaluation import mask_iou  # noqa: E402
from csgs_codec.semantic.selection import (  # noqa: E402
    DEFAULT_THRESHOLD,
    MIN_CLICK_ALPHA,
    click_selection,
    render_feature_map,
)
from csgs_codec.train import defaults  # noqa: E402

REAL = REPO.parent / "shared" / "data" / "real_sh3"
SCENE_FILE = REAL / "fruit_drops.ply"
LABELS_FILE = REAL / "fruit_drops_labels.json"
MODES = ("cosine", "cluster")
#: Figures of the issue (its author's busy machine), for the comparison in the document.
ISSUE_FIGURES = {
    "stage2": {"file_kb_q5": 62.6, "semantic_share_percent_q5": 15.3,
               "miou_3d_uncompressed": {"cosine": 0.71, "cluster": 0.86},
               "miou_3d_q5": {"cosine": 0.69, "cluster": 0.85}},
    "stage2+3": {"file_kb_q5": 54.7, "semantic_share_percent_q5": 3.1,
                 "miou_3d_uncompressed": {"cosine": 0.12, "cluster": 0.20},
                 "miou_3d_q5": {"cosine": 0.04, "cluster": 0.07}},
    "labels": {"file_kb_q5": 54.9, "semantic_share_percent_q5": 3.5,
               "miou_3d_label_under_click": 0.82},
}


@dataclass
class Protocol:
    """Settings of one measurement (defaults: the issue's protocol)."""

    views: int = 32
    width: int = 320
    height: int = 240
    hold_every: int = 4
    stage2_iterations: int = defaults.SEMANTIC_ITERATIONS
    stage3_iterations: int = 100
    rate_weight: float = defaults.FEATURE_RATE_WEIGHT
    margin: float = defaults.CONTRASTIVE_MARGIN
    qualities: tuple[int, ...] = (3, 5, 8)
    threshold: float = DEFAULT_THRESHOLD
    min_pixels: int = 1
    noisy_masks: bool = False
    merged: bool = False
    merged_share: float = 0.2
    seed: int = 0


@dataclass
class Click:
    """One click: held-out view ``view``, category ``label`` at pixel (x, y)."""

    view: int
    label: int
    x: float
    y: float
    pixels: int


def read_labels(path: str | Path) -> tuple[np.ndarray, dict]:
    """(N,) int32 labels (0 unlabelled) and facts about the file, from a segments.ai
    point-cloud segmentation export (module notes)."""
    document_ = json.loads(Path(path).read_text())
    dataset = document_.get("dataset", document_)
    sample = dataset["samples"][0]
    attributes = sample["labels"]["ground-truth"]["attributes"]
    values = np.asarray(attributes["point_annotations"], np.float64)
    if not np.all(values == np.rint(values)) or values.min() < 0:
        raise SystemExit(f"{path}: point_annotations are not non-negative whole numbers")
    labels = values.astype(np.int32)
    categories = dataset.get("task_attributes", {}).get("categories", [])
    used, counts = np.unique(labels, return_counts=True)
    return labels, {
        "path": "dataset.samples[0].labels['ground-truth'].attributes.point_annotations",
        "format": dataset.get("task_type"), "sample": sample.get("name"),
        "points": int(labels.size), "categories_declared": len(categories),
        "categories_used": int(np.count_nonzero(used)),
        "gaussians_per_label": {str(int(k)): int(c) for k, c in zip(used, counts)},
    }


def load_real_scene(scene_path: Path = SCENE_FILE, labels_path: Path = LABELS_FILE
                    ) -> tuple[GaussianScene, np.ndarray, dict]:
    """The fruit-drops scene, its labels and the facts of the label file."""
    from csgs_codec import read_ply

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*ignoring unknown PLY properties.*")
        scene = read_ply(scene_path)
    labels, facts = read_labels(labels_path)
    if labels.shape != (len(scene),):
        raise SystemExit(f"{labels_path}: {labels.size} labels for {len(scene)} Gaussians")
    return scene, labels, facts


def render_classes(labels: np.ndarray) -> tuple[np.ndarray, int]:
    """(N,) classes 1..K + 1 (unlabelled -> K + 1) and K, for masks and the 2D IoU."""
    k = int(labels.max())
    return np.where(labels == 0, k + 1, labels).astype(np.int32), k


def ground_truth_mask(scene: GaussianScene, classes: np.ndarray, camera) -> np.ndarray:
    """(H, W) int32 instance mask: 0 empty, else the class rendered most (module notes)."""
    from csgs_codec.train.synthetic import instance_mask

    return instance_mask(dataclasses.replace(scene, labels=classes, semantic=None,
                                             semantic_names=()), camera)


def jitter_boundaries(mask: np.ndarray, rng: np.random.Generator, radius: int = 2
                      ) -> np.ndarray:
    """``mask`` with every pixel's id taken from a pixel up to ``radius`` away per axis."""
    height, width = mask.shape
    dy, dx = rng.integers(-radius, radius + 1, size=(2, height, width))
    rows = np.clip(np.arange(height)[:, None] + dy, 0, height - 1)
    cols = np.clip(np.arange(width)[None, :] + dx, 0, width - 1)
    return mask[rows, cols]


def merge_objects(masks: list[np.ndarray], categories: int, rng: np.random.Generator,
                  share: float) -> tuple[list[np.ndarray], list[dict]]:
    """Copies of ``masks`` where, in ``share`` of them, two visible categories share one id."""
    out = [m.copy() for m in masks]
    merges = []
    candidates = [i for i, m in enumerate(masks)
                  if np.count_nonzero(np.isin(np.unique(m), np.arange(1, categories + 1))) >= 2]
    count = min(len(candidates), int(round(share * len(masks))))
    for i in sorted(rng.choice(candidates, size=count, replace=False).tolist()):
        visible = [k for k in np.unique(out[i]) if 1 <= k <= categories]
        a, b = sorted(rng.choice(visible, size=2, replace=False).tolist())
        out[i][out[i] == b] = a
        merges.append({"train_view": i, "kept": a, "merged": b})
    return out, merges


def click_points(mask: np.ndarray, categories: int, view: int, min_pixels: int
                 ) -> list[Click]:
    """Per visible category, the mask pixel nearest the mask's centroid (pixel centre)."""
    clicks = []
    for label in range(1, categories + 1):
        rows, cols = np.nonzero(mask == label)
        if rows.size < max(min_pixels, 1):
            continue
        nearest = int(np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2))
        clicks.append(Click(view, label, cols[nearest] + 0.5, rows[nearest] + 0.5, rows.size))
    return clicks


def selection_mask_2d(scene: GaussianScene, classes: np.ndarray, selected: np.ndarray,
                      camera, backend: str = "numba") -> np.ndarray:
    """(H, W) bool pixels where the selection wins the rendered argmax (module notes)."""
    from csgs_codec.render.rasterizer import render

    count = int(classes.max())
    one_hot = np.zeros((len(scene), count + 1), np.float32)
    column = np.where(selected, 0, classes)
    one_hot[np.arange(len(scene)), column] = 1.0
    out = render(scene, camera, features=one_hot, backend=backend)
    weights = np.concatenate([(1.0 - out.alpha)[..., None], out.features], axis=2)
    return np.argmax(weights, axis=2) == 1


def label_under_click(scene: GaussianScene, labels: np.ndarray, camera, clicks: list[Click],
                      backend: str = "numba") -> list[np.ndarray | None]:
    """Per click, the Gaussians whose label is the one rendered most at the click, or None
    where nothing is under it (accumulated opacity below MIN_CLICK_ALPHA)."""
    from csgs_codec.render.rasterizer import render

    one_hot = np.zeros((len(scene), int(labels.max()) + 1), np.float32)
    one_hot[np.arange(len(scene)), labels] = 1.0
    out = render(scene, camera, features=one_hot, backend=backend)
    picks = []
    for click in clicks:
        row, col = int(click.y), int(click.x)
        if not out.alpha[row, col] >= MIN_CLICK_ALPHA:
            picks.append(None)
            continue
        picks.append(labels == int(np.argmax(out.features[row, col])))
    return picks


def evaluate_clicks(scene: GaussianScene, labels: np.ndarray, cameras: list,
                    masks: list[np.ndarray], clicks: list[Click], modes: tuple[str, ...],
                    threshold: float) -> dict:
    """mIoU (3D and 2D) per mode over all clicks on ``scene`` (``labels`` in its order);
    mode "label" selects by the decoded labels (``scene.labels``)."""
    classes, _ = render_classes(labels)
    by_view: dict[int, list[Click]] = {}
    for click in clicks:
        by_view.setdefault(click.view, []).append(click)
    scores = {mode: {"iou_3d": [], "iou_2d": [], "misses": 0, "selected": [],
                     "labels": []} for mode in modes}
    for view, view_clicks in by_view.items():
        camera, truth = cameras[view], masks[view]
        selections = {}
        if "label" in modes:
            selections["label"] = label_under_click(scene, scene.labels, camera, view_clicks)
        rules = [mode for mode in modes if mode != "label"]
        feature_map = (render_feature_map(scene, camera)
                       if set(rules) & {"cosine", "cluster"} else None)
        for mode in rules:
            selections[mode] = []
            for click in view_clicks:
                try:
                    selections[mode].append(click_selection(
                        scene, camera, click.x, click.y, threshold=threshold, mode=mode,
                        feature_map=feature_map if mode != "instance" else None).mask)
                except InputError:  # background or an all-zero feature under the click
                    selections[mode].append(None)
        for mode, picks in selections.items():
            row = scores[mode]
            for click, selected in zip(view_clicks, picks):
                row["labels"].append(click.label)
                if selected is None:
                    row["misses"] += 1
                    row["iou_3d"].append(0.0)
                    row["iou_2d"].append(0.0)
                    row["selected"].append(0)
                    continue
                row["iou_3d"].append(mask_iou(selected, labels == click.label))
                row["iou_2d"].append(mask_iou(
                    selection_mask_2d(scene, classes, selected, camera).ravel(),
                    (truth == click.label).ravel()))
                row["selected"].append(int(np.count_nonzero(selected)))
    return {mode: _summary(row) for mode, row in scores.items()}


def _summary(row: dict) -> dict:
    labels = np.asarray(row["labels"])
    iou_3d, iou_2d = np.asarray(row["iou_3d"]), np.asarray(row["iou_2d"])
    return {
        "miou_3d": float(iou_3d.mean()) if iou_3d.size else 0.0,
        "miou_2d": float(iou_2d.mean()) if iou_2d.size else 0.0,
        "clicks": int(labels.size), "misses": row["misses"],
        "median_selected_gaussians": float(np.median(row["selected"])) if row["selected"]
        else 0.0,
        "miou_3d_per_category": {str(k): round(float(iou_3d[labels == k].mean()), 4)
                                 for k in np.unique(labels)},
    }


def feature_facts(features: np.ndarray, labels: np.ndarray, seen: np.ndarray,
                  threshold: float) -> dict:
    """What decides cosine selection: feature norms, rows that round to zero, how tightly
    each category's features point one way and how far apart the categories point."""
    norms = np.linalg.norm(features, axis=1)
    zero = ~np.any(np.rint(features) != 0, axis=1)
    units, valid = unit_rows(features)
    categories = [k for k in np.unique(labels) if k > 0]
    means, within, tight = [], [], []
    for k in categories:
        member = (labels == k) & valid
        mean = units[member].mean(axis=0)
        mean /= max(float(np.linalg.norm(mean)), 1e-12)
        cosines = units[member] @ mean
        means.append(mean)
        within.append(float(np.mean(cosines)))
        tight.append(float(np.mean(cosines >= threshold)))
    means = np.asarray(means)
    centre = features.mean(axis=0)
    between = means @ means.T
    np.fill_diagonal(between, -1.0)
    return {
        "norm_steps_percentiles_10_50_90": [round(float(v), 4)
                                            for v in np.percentile(norms, [10, 50, 90])],
        "norm_steps_seen_median": float(np.median(norms[seen])) if seen.any() else 0.0,
        "norm_steps_unseen_median": float(np.median(norms[~seen])) if (~seen).any() else 0.0,
        "mean_feature_norm_steps": round(float(np.linalg.norm(centre)), 4),
        "median_distance_to_mean_feature_steps": round(float(np.median(
            np.linalg.norm(features - centre, axis=1))), 4),
        "rounds_to_zero_share": float(np.mean(zero)),
        "rounds_to_zero_share_seen": float(np.mean(zero[seen])) if seen.any() else 0.0,
        "mean_cosine_to_category_direction": round(float(np.mean(within)), 4),
        "share_within_threshold_of_category_direction": round(float(np.mean(tight)), 4),
        "max_cosine_between_category_directions": round(float(between.max()), 4)
        if len(categories) > 1 else None,
    }


def train_features(scene: GaussianScene, cameras: list, masks: list[np.ndarray],
                   protocol: Protocol, matrices: list | None = None) -> dict:
    """Stages 2 and 3 on fixed Gaussians: features, losses, estimated bits, seconds."""
    import torch

    from csgs_codec.train.semantic_stage import (
        SemanticView,
        prepare_semantic_views,
        train_semantic_features,
    )
    from csgs_codec.train.views import TrainingView

    seconds = {}
    if matrices is None:
        began = time.perf_counter()
        views = [TrainingView(np.zeros((c.height, c.width, 3), np.float32), c, m)
                 for c, m in zip(cameras, masks)]
        matrices = [v.contributions for v in prepare_semantic_views(scene, views)]
        seconds["contribution_matrices"] = time.perf_counter() - began
    prepared = [SemanticView(c, torch.as_tensor(m.astype(np.int64)))
                for c, m in zip(matrices, masks)]
    began = time.perf_counter()
    stage2 = train_semantic_features(prepared, len(scene), iterations=protocol.stage2_iterations,
                                     seed=protocol.seed, margin=protocol.margin)
    seconds["stage2"] = time.perf_counter() - began
    began = time.perf_counter()
    stage3 = train_semantic_features(prepared, len(scene), iterations=protocol.stage3_iterations,
                                     rate_weight=protocol.rate_weight, seed=protocol.seed + 1,
                                     initial_features=stage2.features, margin=protocol.margin)
    seconds["stage3"] = time.perf_counter() - began
    return {"matrices": matrices, "stage2": stage2, "stage3": stage3, "seconds": seconds}


def segment(scene: GaussianScene, cameras: list, masks: list[np.ndarray], protocol: Protocol
            ) -> tuple[GaussianScene, dict]:
    """``csgs segment``'s library call on the training views: the segmented scene and facts
    (instances, their sizes, the stage-2 loss, seconds per phase)."""
    from csgs_codec.train.segment import SegmentSettings, segment_scene
    from csgs_codec.train.views import TrainingView

    views = [TrainingView(np.zeros((c.height, c.width, 3), np.float32), c, m)
             for c, m in zip(cameras, masks)]
    result = segment_scene(scene, views, SegmentSettings(
        iterations=protocol.stage2_iterations, margin=protocol.margin, seed=protocol.seed))
    instances = result.instances
    return result.scene, {
        "instances": instances.count, "objects_before_empty_dropped": instances.objects,
        "gaussians_per_instance": instances.counts.tolist(),
        "stage2_final_loss": float(result.losses[-1]),
        "seconds": result.seconds,
    }


def coded_rows(scene: GaussianScene, labels: np.ndarray, variant: str,
               features: np.ndarray | None, protocol: Protocol, cameras: list,
               masks: list[np.ndarray], clicks: list[Click], seen: np.ndarray, *,
               modes: tuple[str, ...] | None = None, scaled: bool = True) -> list[dict]:
    """The variant uncompressed and at every quality: bytes, seconds, click scores.
    ``scaled`` features are multiplied by the preset's semantic step (module notes, Scaling);
    unscaled ones are coded as they are (``csgs segment``'s prototypes)."""
    if modes is None:
        modes = ("label", "instance") if features is None else MODES
    names = tuple(f"sem_{i}" for i in range(0 if features is None else features.shape[1]))
    rows = []
    for quality in (None, *protocol.qualities):
        row = {"variant": variant, "coding": "uncompressed" if quality is None
               else f"quality {quality}", "quality": quality}
        if features is None:
            source = dataclasses.replace(scene, semantic=None, semantic_names=(),
                                         labels=labels.astype(np.int32))
        else:
            step = 1.0 if quality is None or not scaled else PRESETS[quality].semantic_step
            source = dataclasses.replace(scene, labels=None, semantic_names=names,
                                         semantic=(features * np.float32(step)
                                                   ).astype(np.float32))
            row["semantic_step"] = step
        order = np.arange(len(scene))
        evaluated = source
        if quality is not None:
            began = time.perf_counter()
            report = Encoder(quality=quality).encode_with_report(source)
            row["encode_s"] = time.perf_counter() - began
            began = time.perf_counter()
            evaluated = Decoder().decode(report.data, layers="color,semantic")
            row["decode_s"] = time.perf_counter() - began
            order = report.order
            if len(evaluated) != len(scene):
                raise SystemExit(f"{variant} at quality {quality}: {len(evaluated)} Gaussians "
                                 f"decoded of {len(scene)}")
            facts = describe_bitstream(report.data)
            row.update(file_bytes=facts["file_bytes"],
                       semantic_bytes=facts["layers"]["semantic"]["bytes"],
                       semantic_share_percent=facts["semantic_share_percent"],
                       semantic_bits_per_gaussian=8 * facts["layers"]["semantic"]["bytes"]
                       / len(scene))
            if features is not None:
                decoded = evaluated.semantic.astype(np.float64) / step
                row["all_zero_features_share"] = float(np.mean(~np.any(decoded != 0, axis=1)))
            elif not np.array_equal(evaluated.labels, labels[order]):
                raise SystemExit(f"labels changed in the round trip at quality {quality}")
        elif features is not None:
            row["all_zero_features_share"] = float(np.mean(~np.any(features != 0, axis=1)))
        began = time.perf_counter()
        row["selection"] = evaluate_clicks(evaluated, labels[order], cameras, masks, clicks,
                                           modes, protocol.threshold)
        row["clicks_s"] = time.perf_counter() - began
        if features is not None and quality is None:
            row["features"] = feature_facts(features, labels, seen, protocol.threshold)
        rows.append(row)
        print(f"  {variant} {row['coding']}: " + ", ".join(
            f"{m} 3D {s['miou_3d']:.3f} 2D {s['miou_2d']:.3f}"
            for m, s in row["selection"].items()), file=sys.stderr)
    return rows


def measure(scene: GaussianScene, labels: np.ndarray, protocol: Protocol) -> tuple[list, dict]:
    """The whole protocol on ``scene`` with per-Gaussian ``labels`` (0 unlabelled): result
    rows and the document's other fields."""
    seconds: dict = {}
    classes, categories = render_classes(labels)
    cameras = orbit_cameras(scene, protocol.views, width=protocol.width, height=protocol.height)
    began = time.perf_counter()
    masks = [ground_truth_mask(scene, classes, c) for c in cameras]
    seconds["ground_truth_masks"] = time.perf_counter() - began
    held = [i for i in range(len(cameras)) if protocol.hold_every and i % protocol.hold_every == 0]
    train = [i for i in range(len(cameras)) if i not in held]
    clicks = [c for i in held for c in click_points(masks[i], categories, i,
                                                    protocol.min_pixels)]
    if not clicks:
        raise SystemExit("no category is visible in any held-out view")
    train_cameras = [cameras[i] for i in train]
    clean = [masks[i] for i in train]
    conditions = {"clean": (clean, None)}
    rng = np.random.default_rng([protocol.seed, 30])
    if protocol.noisy_masks:
        conditions["noisy"] = ([jitter_boundaries(m, rng) for m in clean], None)
    if protocol.merged:
        conditions["merged"] = merge_objects(clean, categories, rng, protocol.merged_share)
    import torch

    results, training, matrices, seen = [], {}, None, None
    for condition, (train_masks, merges) in conditions.items():
        print(f"{condition} masks: stages 2 and 3", file=sys.stderr)
        trained = train_features(scene, train_cameras, train_masks, protocol, matrices)
        if matrices is None:
            matrices = trained["matrices"]
            seen = sum(torch.sparse.sum(m, dim=0).to_dense() for m in matrices).numpy() > 0
        seconds[condition] = trained["seconds"]
        training[condition] = {
            "stage2_final_loss": float(trained["stage2"].losses[-1]),
            "stage3_final_loss": float(trained["stage3"].losses[-1]),
            "stage3_estimated_bits_per_gaussian_first_last": [
                float(trained["stage3"].bits[0]), float(trained["stage3"].bits[-1])]
            if protocol.stage3_iterations else None,
            "merges": merges,
            "stage3_rate_model": _prior_facts(trained["stage3"].rate_model),
        }
        for variant, stage in (("stage2", "stage2"), ("stage2+3", "stage3")):
            for row in coded_rows(scene, labels, variant, trained[stage].features, protocol,
                                  cameras, masks, clicks, seen):
                results.append({"masks": condition, **row})
        print(f"{condition} masks: segment", file=sys.stderr)
        segmented, segment_facts = segment(scene, train_cameras, train_masks, protocol)
        seconds[condition]["segment"] = segment_facts.pop("seconds")
        training[condition]["segment"] = segment_facts
        for row in coded_rows(scene, labels, "segment", segmented.semantic, protocol, cameras,
                              masks, clicks, seen, modes=("instance",), scaled=False):
            results.append({"masks": condition, **row})
    one_hot = np.zeros((len(scene), categories + 1), np.float32)
    one_hot[np.arange(len(scene)), labels] = 1.0
    for variant, features in (("onehot", one_hot), ("labels", None)):
        for row in coded_rows(scene, labels, variant, features, protocol, cameras, masks,
                              clicks, seen):
            results.append({"masks": "clean", **row})
    extra = {
        "views": {"count": len(cameras), "train": len(train), "held_out": len(held),
                  "size": f"{protocol.width}x{protocol.height}", "held_out_ids": held},
        "clicks": {"count": len(clicks), "per_view": {str(i): sum(c.view == i for c in clicks)
                                                      for i in held},
                   "median_mask_pixels": float(np.median([c.pixels for c in clicks])),
                   "pixel_mix": clicked_pixel_mix(scene, classes, cameras, clicks,
                                                  protocol.threshold)},
        "gaussians": len(scene), "categories": categories,
        "seen_in_training_views_share": float(np.mean(seen)),
        "training": training, "seconds": _rounded(seconds),
    }
    return results, extra


def _prior_facts(model) -> dict | None:
    """The learned per-channel mean and sigma (steps) of a factorized stage-3 prior."""
    if model is None or not hasattr(model, "log_sigma"):
        return None
    return {"mean": [round(float(v), 4) for v in model.mean.detach().cpu()],
            "sigma": [round(float(v), 4) for v in model.log_sigma.detach().exp().cpu()]}


def clicked_pixel_mix(scene: GaussianScene, classes: np.ndarray, cameras: list,
                      clicks: list[Click], threshold: float) -> dict:
    """How pure the clicked pixels are: the clicked category's share of the pixel's rendered
    class weights, and the share of clicks where even one-hot features would pass the cosine
    threshold (the category's weight over the norm of the pixel's weight vector)."""
    from csgs_codec.render.rasterizer import render

    one_hot = np.zeros((len(scene), int(classes.max()) + 1), np.float32)
    one_hot[np.arange(len(scene)), classes] = 1.0
    shares, cosines = [], []
    for view in sorted({c.view for c in clicks}):
        weights = render(scene, cameras[view], features=one_hot, backend="numba").features
        for click in (c for c in clicks if c.view == view):
            pixel = weights[int(click.y), int(click.x)].astype(np.float64)
            shares.append(pixel[click.label] / pixel.sum())
            cosines.append(pixel[click.label] / np.linalg.norm(pixel))
    return {"category_share_of_pixel_weight_percentiles_10_50_90": [
                round(float(v), 4) for v in np.percentile(shares, [10, 50, 90])],
            "one_hot_cosine_passes_threshold_share": float(np.mean(np.asarray(cosines)
                                                                   >= threshold))}


def _rounded(value):
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    return round(value, 3) if isinstance(value, float) else value


def build_document(scene: GaussianScene, labels: np.ndarray, protocol: Protocol, *,
                   scene_name: str, label_facts: dict | None = None, notes: str = "") -> dict:
    """:func:`measure` as a csgs-bench/1 document."""
    began = time.perf_counter()
    results, extra = measure(scene, labels, protocol)
    extra["seconds"]["total"] = round(time.perf_counter() - began, 3)
    return document("selection_real", results, scene=scene_name, label_file=label_facts,
                    protocol=dataclasses.asdict(protocol), issue_figures=ISSUE_FIGURES,
                    notes=notes, **extra)


def main() -> int:
    """Parse arguments, run, print or write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="write the JSON here instead of printing it")
    parser.add_argument("--views", type=int, default=Protocol.views)
    parser.add_argument("--size", default=f"{Protocol.width}x{Protocol.height}")
    parser.add_argument("--stage2-iterations", type=int, default=Protocol.stage2_iterations)
    parser.add_argument("--stage3-iterations", type=int, default=Protocol.stage3_iterations)
    parser.add_argument("--qualities", type=int, nargs="+", default=list(Protocol.qualities))
    parser.add_argument("--min-pixels", type=int, default=Protocol.min_pixels,
                        help="smallest ground-truth mask (pixels) of a category clicked")
    parser.add_argument("--noisy-masks", action="store_true",
                        help="also train on masks with +-2 px boundary noise")
    parser.add_argument("--merged", action="store_true",
                        help="also train with two objects sharing a mask in 20%% of views")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    parser.add_argument("--notes", default="", help="recorded in the document")
    args = parser.parse_args()
    if not REAL.is_dir():
        print(f"{REAL} is absent: this benchmark needs ../shared/data/real_sh3 "
              "(fruit_drops.ply and fruit_drops_labels.json)", file=sys.stderr)
        return 2
    import torch

    torch.set_num_threads(args.threads)
    width, height = (int(v) for v in args.size.split("x"))
    protocol = Protocol(views=args.views, width=width, height=height,
                        stage2_iterations=args.stage2_iterations,
                        stage3_iterations=args.stage3_iterations,
                        qualities=tuple(args.qualities), min_pixels=args.min_pixels,
                        noisy_masks=args.noisy_masks, merged=args.merged)
    scene, labels, facts = load_real_scene()
    emit(build_document(scene, labels, protocol, scene_name=SCENE_FILE.name,
                        label_facts=facts, notes=args.notes), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
