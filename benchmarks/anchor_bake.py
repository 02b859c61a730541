"""How much an anchor scene loses when baked into a standard 3DGS scene (issue 51, item 2).

Trains an anchor scene with ``csgs train`` (by default the demo's tiny synthetic capture, made
here), then on its held-out views scores against the photos (PSNR / SSIM): the exact per-view
anchor render, and the bakes over the file's stored training origins (unrefined, as the
browser page bakes, and refined as ``csgs decode -o x.ply`` does by default) and over the
default sphere; and the bakes against the exact render. Also reports
Gaussians and bytes of the anchor file, the baked PLY and SPZ, and the baked scene's default
standard encode.

Usage::

    python benchmarks/anchor_bake.py --out benchmarks/results/anchor_bake_DATE.json
    python benchmarks/anchor_bake.py --dataset DIR --train-args "--resolution 384" --out F
    python benchmarks/anchor_bake.py --dataset DIR --anchor-file F.csgs --downscale 6 \
        --test-every 8 --out F

A capture with foreground masks (its ``masks/`` of 0/255 images, as ``csgs train`` finds
them) is scored as training saw it: photos composited over black outside the object.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_common import machine

#: Refinement steps of the refined bake (csgs decode's default).
REFINE_STEPS = 300
DEMO_TRAIN = ("--iterations 300 --anchors 150 --features 16 --offsets 5 "
              "--semantic-iterations 60 --test-every 4")
TEST_EVERY = 4


def scores(views, gaussians_for) -> dict:
    """Mean PSNR / SSIM over ``views`` of renders of ``gaussians_for(camera)`` vs photos."""
    from csgs_codec.metrics.image import psnr, ssim
    from csgs_codec.render.rasterizer import render

    p, s = [], []
    for view in views:
        image = np.clip(render(gaussians_for(view.camera), view.camera,
                               backend="numba").image, 0, 1)
        p.append(psnr(view.image, image))
        s.append(ssim(view.image, image))
    return {"psnr": float(np.mean(p)), "ssim": float(np.mean(s))}


def against_exact(views, exact, baked) -> float:
    """Mean PSNR of the bake's renders against the exact anchor renders."""
    from csgs_codec.metrics.image import psnr
    from csgs_codec.render.rasterizer import render

    return float(np.mean([
        psnr(np.clip(render(exact.gaussians(v.camera), v.camera, backend="numba").image, 0, 1),
             np.clip(render(baked, v.camera, backend="numba").image, 0, 1))
        for v in views]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", help="capture to train (default: the demo's synthetic)")
    parser.add_argument("--train-args", default=DEMO_TRAIN)
    parser.add_argument("--anchor-file", help="score this trained file of --dataset instead "
                        "of training one")
    parser.add_argument("--downscale", type=float, default=1.0,
                        help="load the held-out photos at 1/this size (the training size)")
    parser.add_argument("--test-every", type=int, default=TEST_EVERY,
                        help="the held-out views: every K-th (as csgs train --test-every)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    from csgs_codec import Encoder, write_scene
    from csgs_codec.bake.anchor_bake import BakeSettings, bake_anchor_scene, bake_origins
    from csgs_codec.codec.anchor_decoder import AnchorDecoder
    from csgs_codec.model.anchor_views import SceneViews
    from csgs_codec.train.datasets import find_foreground_masks, load_dataset
    from csgs_codec.train.evaluation import split_views

    csgs = str(Path(sys.executable).with_name("csgs"))
    work = Path(tempfile.mkdtemp(prefix="anchor_bake_"))
    dataset = args.dataset
    if dataset is None:
        dataset = str(work / "synthetic")
        subprocess.run([csgs, "synthetic", dataset, "--views", "12", "--size", "64x48",
                        "--gaussians", "200", "--quiet"], check=True)
    train_seconds = None
    if args.anchor_file:
        anchor_file = Path(args.anchor_file)
    else:
        anchor_file = work / "scene.csgs"
        began = time.perf_counter()
        subprocess.run([csgs, "train", dataset, "-o", str(anchor_file), "--quiet",
                        *shlex.split(args.train_args)], check=True)
        train_seconds = time.perf_counter() - began
    scene = AnchorDecoder().decode(anchor_file, layers="color,semantic")
    exact = SceneViews(scene)
    foreground = find_foreground_masks(dataset)
    views = load_dataset(dataset, read_masks=False, downscale=args.downscale,
                         foreground=foreground)
    _, test = split_views(views, args.test_every)
    rows = []
    exact_scores = scores(test, exact.gaussians)
    rows.append({"scene": "exact per-view anchors", "gaussians_per_view": None,
                 **exact_scores, "vs_exact_psnr": None, "bytes": anchor_file.stat().st_size})
    for label, origins, refine in (
            ("bake over stored training origins", None, 0),
            (f"bake over stored training origins, refined {REFINE_STEPS} steps", None,
             REFINE_STEPS),
            ("bake over default sphere", bake_origins(scene), 0)):
        began = time.perf_counter()
        baked = bake_anchor_scene(scene, origins=origins,
                                  settings=BakeSettings(refine_steps=refine))
        bake_seconds = time.perf_counter() - began
        ply, spz = work / "baked.ply", work / "baked.spz"
        write_scene(baked, ply)
        write_scene(baked, spz)
        standard = Encoder().encode(baked)
        got = scores(test, lambda camera, b=baked: b)
        rows.append({"scene": label, "gaussians": len(baked), **got,
                     "loss_vs_exact_db": exact_scores["psnr"] - got["psnr"],
                     "vs_exact_psnr": against_exact(test, exact, baked),
                     "bake_seconds": bake_seconds, "ply_bytes": ply.stat().st_size,
                     "spz_bytes": spz.stat().st_size, "standard_csgs_bytes": len(standard)})
    doc = {"schema": "csgs-bench/1", "benchmark": "anchor_bake", "machine": machine(),
           "dataset": args.dataset or "demo synthetic (csgs synthetic --views 12 --size 64x48)",
           "train_args": None if args.anchor_file else args.train_args,
           "anchor_file": args.anchor_file, "train_seconds": train_seconds,
           "foreground_masks": foreground is not None, "downscale": args.downscale,
           "anchors": len(scene), "slots": scene.active_offsets(),
           "held_out_views": len(test), "results": rows}
    Path(args.out).write_text(json.dumps(doc, indent=2) + "\n")
    for row in rows:
        print(row)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
