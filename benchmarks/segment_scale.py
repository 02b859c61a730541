"""`csgs segment` at scale: time and accuracy of segment_scene on large synthetic scenes.

    python benchmarks/segment_scale.py [--device cpu|cuda] [--objects 10]
        [--gaussians 5000] [--views 24] [--size 512x384] [--iterations 150] [--out FILE]

A seeded synthetic dataset (csgs_codec/train/synthetic.py: ``--objects`` labelled shells of
``--gaussians`` Gaussians each, ``--views`` orbit views at ``--size`` with their exact
instance masks) is segmented from its cameras and masks alone
(csgs_codec.train.segment.segment_scene, the defaults of ``csgs segment`` but the steps).
Reported: seconds per phase (compositing the views into contribution lists, stage 2, lifting
instances), the contributing pairs kept, the instances found, and per object the IoU of the
instance holding most of its Gaussians with the object (and their mean); then the .csgs the
default encoder writes for the segmented scene (quality 5) and its semantic share. The JSON
(schema csgs-bench/1) records the device and, on CUDA, the peak GPU memory.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_common import document, emit  # noqa: E402


def object_ious(ids, labels) -> list[float]:
    """Per object, the IoU of the instance holding most of its Gaussians with the object."""
    import numpy as np

    ious = []
    for label in np.unique(labels):
        values, counts = np.unique(ids[labels == label], return_counts=True)
        members = ids == values[np.argmax(counts)]
        truth = labels == label
        ious.append(float(np.sum(members & truth) / np.sum(members | truth)))
    return ious


def measure(args) -> dict:
    """One run: the result row."""
    import numpy as np
    import torch

    from csgs_codec.codec.describe import describe_bitstream
    from csgs_codec.codec.encoder import Encoder
    from csgs_codec.train.segment import SegmentSettings, segment_scene
    from csgs_codec.train.synthetic import make_synthetic_dataset

    width, height = (int(v) for v in args.size.split("x"))
    began = time.perf_counter()
    data = make_synthetic_dataset(args.seed, objects=args.objects,
                                  gaussians_per_object=args.gaussians, views=args.views,
                                  width=width, height=height)
    dataset_s = time.perf_counter() - began
    if args.device.startswith("cuda"):
        torch.cuda.reset_peak_memory_stats()
    result = segment_scene(data.scene, data.views, SegmentSettings(
        iterations=args.iterations, device=args.device, seed=args.seed))
    ious = object_ious(result.instances.ids, data.scene.labels)
    unlabelled = data.scene.subset(np.arange(len(data.scene)))
    unlabelled.labels = None
    segmented = result.scene.subset(np.arange(len(result.scene)))
    segmented.labels = None
    began = time.perf_counter()
    encoded = Encoder(quality=5).encode(segmented)
    encode_s = time.perf_counter() - began
    facts = describe_bitstream(encoded)
    row = {
        "device": args.device, "gaussians": len(data.scene), "objects": args.objects,
        "views": args.views, "size": args.size, "iterations": args.iterations,
        "seconds": {**{k: round(v, 3) for k, v in result.seconds.items()},
                    "dataset": round(dataset_s, 3), "encode_q5": round(encode_s, 3)},
        "instances": result.instances.count,
        "object_iou_mean": float(np.mean(ious)), "object_iou_min": float(np.min(ious)),
        "file_bytes_q5": facts["file_bytes"],
        "semantic_share_percent_q5": facts["semantic_share_percent"],
        "semantic_bits_per_gaussian_q5": 8 * facts["layers"]["semantic"]["bytes"]
        / len(data.scene),
    }
    if args.device.startswith("cuda"):
        row["peak_gpu_memory_mb"] = torch.cuda.max_memory_allocated() / 2**20
    return row


def main() -> int:
    """Parse arguments, run, print or write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--objects", type=int, default=10)
    parser.add_argument("--gaussians", type=int, default=5000)
    parser.add_argument("--views", type=int, default=24)
    parser.add_argument("--size", default="512x384")
    parser.add_argument("--iterations", type=int, default=150)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: all)")
    parser.add_argument("--notes", default="")
    parser.add_argument("--out")
    args = parser.parse_args()
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    row = measure(args)
    emit(document("segment_scale", [row], notes=args.notes), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
