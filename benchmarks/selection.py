"""Click selection from the decoded semantic layer against the uncompressed features (issue 8).

For labelled synthetic scenes (csgs_codec/semantic/synthetic.py) seen by a camera above them,
every object's projected centre is clicked and the selection scored by IoU with the object's
Gaussians; mIoU is the mean over objects. Per quality 1..9 the scene is encoded (labels left
out, so the semantic layer holds the features only), decoded with ``layers="color,semantic"``
and clicked again. Reported: mIoU raw and decoded, the drop in mIoU points, the semantic
layer's bytes and its share of the file. Targets (issue 8): drop <= 1 mIoU point, share <= 4%.

Anchor scenes (Scaffold-GS, csgs_codec/scene/synthetic_anchors.py) go through AnchorEncoder /
AnchorDecoder the same way; there the elements are anchors, each shared by K Gaussians.

A step sweep (Gaussian scenes) shows what the semantic quantization step costs in mIoU and in
ideal bytes (order-0 entropy per channel, and within k-means clusters), to guide the choice of
step and of a semantic context model.

Usage: .venv/bin/python benchmarks/selection.py [--out FILE] [--quick]
Writes one JSON document in the csgs-bench/1 schema (see benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import document, emit  # noqa: E402

from csgs_codec.codec.anchor_decoder import AnchorDecoder  # noqa: E402
from csgs_codec.codec.anchor_encoder import AnchorEncoder  # noqa: E402
from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.describe import describe_bitstream  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import PRESETS  # noqa: E402
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene  # noqa: E402
from csgs_codec.semantic.clustering import spherical_kmeans, unit_rows  # noqa: E402
from csgs_codec.semantic.evaluation import click_object_ious, mean_iou  # noqa: E402
from csgs_codec.semantic.selection import DEFAULT_THRESHOLD  # noqa: E402
from csgs_codec.semantic.synthetic import labelled_blob_scene, overview_camera  # noqa: E402

TARGETS = {"miou_drop_points": 1.0, "semantic_share_percent": 4.0}
#: Gaussian scenes: name -> labelled_blob_scene arguments.
SCENES = {
    "5 objects, SH0, noise 0.05": dict(n_objects=5, per_object=2000, sh_degree=0,
                                       semantic_noise=0.05),
    "5 objects, SH3, noise 0.05": dict(n_objects=5, per_object=2000, sh_degree=3,
                                       semantic_noise=0.05),
    "9 objects close, SH3, noise 0.1": dict(n_objects=9, per_object=1000, sh_degree=3,
                                            semantic_noise=0.1, spacing=0.7),
}
#: Anchor scenes: name -> synthetic_anchor_scene arguments (K = 10 Gaussians per anchor).
ANCHOR_SCENES = {
    "anchors: 5 objects x 2000, S = 6": dict(n_objects=5, anchors_per_object=2000),
}
STEP_SWEEP = (1 / 256, 1 / 64, 1 / 16, 1 / 8, 1 / 4)
VIEW_SIZE = (400, 300)


def raw_miou(scene, camera, labels, mode: str = "cosine") -> tuple[float, dict, float]:
    """(mIoU, per-object IoU, seconds per click) from the scene's own features."""
    start = time.perf_counter()
    ious = click_object_ious(scene, camera, labels, mode=mode)
    return mean_iou(ious), ious, (time.perf_counter() - start) / max(len(ious), 1)


def quality_row(scene, camera, labels, quality: int, raw: float, anchors: bool) -> dict:
    """Encode at ``quality``, decode both layers, click every object; sizes and mIoU."""
    encoder, decoder = ((AnchorEncoder, AnchorDecoder) if anchors else (Encoder, Decoder))
    start = time.perf_counter()
    report = encoder(quality=quality).encode_with_report(scene)
    encode_seconds = time.perf_counter() - start
    decoded = decoder().decode(report.data, layers="color,semantic")
    if len(decoded) != len(scene) or decoded.semantic is None:
        raise SystemExit(f"round trip failed at quality {quality}")
    error = float(np.abs(decoded.semantic - scene.semantic[report.order]).max())
    facts = describe_bitstream(report.data)
    ious = click_object_ious(decoded, camera, labels[report.order])
    miou = mean_iou(ious)
    row = {
        "quality": quality, "file_bytes": facts["file_bytes"],
        "semantic_bytes": facts["layers"]["semantic"]["bytes"],
        "semantic_share_percent": facts["semantic_share_percent"],
        "bits_per_element": 8 * facts["file_bytes"] / len(scene),
        "semantic_bits_per_element": 8 * facts["layers"]["semantic"]["bytes"] / len(scene),
        "semantic_max_abs_error": error, "miou_decoded": miou,
        "miou_drop_points": 100 * (raw - miou), "encode_seconds": encode_seconds,
        "ious_decoded": {str(k): v for k, v in ious.items()},
    }
    row["meets_targets"] = (row["miou_drop_points"] <= TARGETS["miou_drop_points"]
                            and row["semantic_share_percent"]
                            <= TARGETS["semantic_share_percent"])
    return row


def step_sweep(scene, camera, labels, other_bytes: int) -> list[dict]:
    """mIoU and ideal semantic bytes when the features are quantized with each step.

    ``ideal_semantic_bytes``: order-0 entropy per channel (a memoryless coder's bound).
    ``ideal_clustered_bytes``: entropy per channel within each of 16 k-means clusters of the
    features plus the cluster index: what a coder that predicts a Gaussian's feature from its
    object (a context or hyperprior) could approach. Shares are against ``other_bytes`` (the
    rest of the quality-5 file).
    """
    units, _ = unit_rows(scene.semantic)
    _, cluster = spherical_kmeans(units, 16)
    rows = []
    for step in STEP_SWEEP:
        symbols = np.round(scene.semantic.astype(np.float64) / step).astype(np.int64)
        plain = sum(_entropy_bits(symbols[:, c]) for c in range(symbols.shape[1])) / 8
        clustered = (_entropy_bits(cluster) + sum(
            _entropy_bits(symbols[cluster == k, c]) for k in np.unique(cluster)
            for c in range(symbols.shape[1]))) / 8
        quantized = scene.subset(np.arange(len(scene)))
        quantized.semantic = (symbols * step).astype(np.float32)
        rows.append({"step": step, "miou": mean_iou(click_object_ious(quantized, camera, labels)),
                     "ideal_semantic_bytes": round(plain),
                     "ideal_share_percent": 100 * plain / (other_bytes + plain),
                     "ideal_clustered_bytes": round(clustered),
                     "ideal_clustered_share_percent": 100 * clustered / (other_bytes + clustered)})
    return rows


def _entropy_bits(values: np.ndarray) -> float:
    """Order-0 entropy of ``values`` times their count, in bits."""
    _, counts = np.unique(values, return_counts=True)
    p = counts / counts.sum()
    return float(-(counts * np.log2(p)).sum())


def scene_result(name: str, scene, quick: bool, anchors: bool) -> dict:
    """Raw and per-quality figures for one labelled scene (labels removed before coding)."""
    qualities = (1, 5, 9) if quick else tuple(range(1, 10))
    camera = overview_camera(scene.positions, width=VIEW_SIZE[0], height=VIEW_SIZE[1])
    labels = scene.labels
    scene.labels = None  # the semantic layer carries the features only
    raw, raw_ious, click_seconds = raw_miou(scene, camera, labels)
    cluster, _, _ = raw_miou(scene, camera, labels, mode="cluster")
    rows = [quality_row(scene, camera, labels, q, raw, anchors) for q in qualities]
    at_5 = next(r for r in rows if r["quality"] == 5)
    result = {
        "scene": name, "kind": "anchors" if anchors else "gaussians",
        "elements": len(scene), "objects": int(labels.max()) + 1,
        "semantic_channels": scene.semantic.shape[1],
        "view": f"{camera.width}x{camera.height}",
        "miou_raw": raw, "miou_raw_cluster_mode": cluster,
        "ious_raw": {str(k): v for k, v in raw_ious.items()},
        "seconds_per_click": click_seconds, "qualities": rows,
        "worst_miou_drop_points": max(r["miou_drop_points"] for r in rows),
        "share_range_percent": [min(r["semantic_share_percent"] for r in rows),
                                max(r["semantic_share_percent"] for r in rows)],
    }
    if not anchors:
        result["step_sweep_at_quality_5"] = step_sweep(
            scene, camera, labels, at_5["file_bytes"] - at_5["semantic_bytes"])
    return result


def run(quick: bool) -> dict:
    """The whole benchmark as a csgs-bench/1 document."""
    results = [scene_result(name, labelled_blob_scene(**options, seed=0), quick, False)
               for name, options in SCENES.items()]
    results += [scene_result(name, synthetic_anchor_scene(**options, seed=0), quick, True)
                for name, options in ANCHOR_SCENES.items()]
    steps = {q: p.semantic_step for q, p in PRESETS.items()}
    return document("selection", results, targets=TARGETS, semantic_steps=steps,
                    threshold=DEFAULT_THRESHOLD, mode="cosine", quick=quick)


def main() -> None:
    """Parse arguments, run, print or write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="write the JSON here instead of printing it")
    parser.add_argument("--quick", action="store_true", help="qualities 1, 5 and 9 only")
    args = parser.parse_args()
    emit(run(args.quick), args.out)


if __name__ == "__main__":
    main()
