"""Training on real content, all three stages, scored on held-out views: a real photo
capture (``--capture``), or views rendered from a shared trained scene.

    .venv/bin/python benchmarks/train_real.py --capture DIR [--resolution 384]
        [--test-every 8] [--lambdas 0.004 0.01 0.02] [--iterations 2000 | --budget S]
        [--anchors 2000] [--max-anchors 20000] [--semantic-iterations 150] [--out FILE]
    .venv/bin/python benchmarks/train_real.py [--scene donut] [--lambdas 0.004 0.01 0.02]
        [--views 24] [--size 160x120] [--iterations 2000] [--anchors 2000] [--out FILE]

With ``--capture`` (a folder ``csgs train`` reads: LLFF, COLMAP, transforms.json, INRIA
cameras.json) the run is ``csgs train DIR --resolution R`` with every other setting at its
default, once per lambda: the photos downscaled so their longer side is R pixels, the
capture's foreground masks when its masks/ folder holds 0/255 ones (the object trained alone
over black), instance masks from the built-in segmenter where the capture has none, every
``--test-every``-th photo held out, the initial points from the capture (or triangulated by
pycolmap, cached). ``--budget`` plans stage 1 from its first steps' speed as
``csgs train --budget`` does.

Without it, the shared scenes come without their training images or cameras
(../shared/data/README.md), so this stands in for a real capture: the scene is rendered from
``--views`` cameras at two elevations (half at 15, half at 45 degrees), every 4th view is held
out, and each view's instance mask comes from
:func:`csgs_codec.train.segmentation.segment_image` (what ``csgs train`` does when a dataset
has no masks). Stage 1 starts from points triangulated by pycolmap from the training views'
images at their known cameras (``--initial-points sfm``, what ``csgs train`` does for a
capture without points), from random points in the ball the cameras look into, or (the
default) from a seeded subset of the scene's own centres.

Per lambda it reports the held-out PSNR/SSIM of the decoded file (and PSNR inside the
foreground masks where the views have them), the file and layer sizes, anchors, the semantic
share, the 2D click mIoU against the segmenter's masks of the held-out views (consistency
with the masks trained on; there is no ground truth), the stage times, wall and CPU seconds
and the process's peak resident memory so far.
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import sys
import time
import warnings
from itertools import zip_longest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import SCENES, document, emit  # noqa: E402
from train import LAYER_CHUNKS  # noqa: E402  (benchmarks/train.py)

from csgs_codec import read_ply  # noqa: E402
from csgs_codec.codec.anchor_decoder import AnchorDecoder  # noqa: E402
from csgs_codec.render.rasterizer import render  # noqa: E402
from csgs_codec.scene.camera import Camera  # noqa: E402
from csgs_codec.scene.orbit import orbit_cameras  # noqa: E402
from csgs_codec.train.color_stage import ColorStageSettings  # noqa: E402
from csgs_codec.train.defaults import (  # noqa: E402
    MAX_ANCHORS,
    RATE_WEIGHT_PRESETS,
    SEMANTIC_ITERATIONS,
)
from csgs_codec.train.evaluation import image_click_miou, score_views, split_views  # noqa: E402
from csgs_codec.train.initial_points import random_points  # noqa: E402
from csgs_codec.train.pipeline import TrainSettings, train_scene  # noqa: E402
from csgs_codec.train.segmentation import segment_image  # noqa: E402
from csgs_codec.train.sfm_points import triangulate_views  # noqa: E402
from csgs_codec.train.views import TrainingView  # noqa: E402


def rendered_views(scene, count: int, width: int, height: int) -> list[TrainingView]:
    """``count`` views of ``scene`` (half at 15, half at 45 degrees elevation) with masks."""
    low = orbit_cameras(scene, count - count // 2, width=width, height=height,
                        elevation_deg=15.0)
    high = orbit_cameras(scene, count // 2, width=width, height=height, elevation_deg=45.0)
    views = []
    interleaved = [c for pair in zip_longest(low, high) for c in pair if c is not None]
    for i, camera in enumerate(interleaved):
        name = f"images/view_{i:03d}.png"
        camera = Camera(camera.width, camera.height, camera.fx, camera.fy, camera.cx,
                        camera.cy, camera.world_to_camera, name=name,
                        near_plane=camera.near_plane)
        image = np.clip(render(scene, camera).image, 0.0, 1.0).astype(np.float32)
        views.append(TrainingView(image, camera, segment_image(image), name=name))
    return views


def peak_rss_bytes() -> int:
    """The process's peak resident memory so far, bytes (Linux reports KiB)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak if sys.platform == "darwin" else peak * 1024)


def capture_views(folder: str, resolution: int, test_every: int, seed: int):
    """(training views, held-out views, initial points, a description of the dataset) of the
    capture in ``folder``, loaded as ``csgs train --resolution`` loads it."""
    from csgs_cli.dataset_input import downscale_for
    from csgs_codec.errors import FallbackWarning
    from csgs_codec.train.datasets import find_foreground_masks, load_dataset
    from csgs_codec.train.initial_points import find_initial_points

    began = time.perf_counter()
    foreground = find_foreground_masks(folder)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FallbackWarning)
        views = load_dataset(folder, downscale=downscale_for(folder, resolution),
                             segment_missing=True, foreground=foreground)
    segmented = any(issubclass(w.category, FallbackWarning) for w in caught)
    train, test = split_views(views, test_every)
    points, source = find_initial_points(folder, [v.camera for v in train], seed=seed,
                                         views=train)
    dataset = {"capture": os.path.abspath(folder), "views": len(views),
               "train_views": len(train), "test_views": len(test),
               "width": views[0].width, "height": views[0].height,
               "foreground_masks": None if foreground is None else str(foreground),
               "masks": ("built-in segmenter (the capture has no instance masks)" if segmented
                         else "the capture's"),
               "initial_points": source, "initial_point_count": len(points),
               "load_seconds": round(time.perf_counter() - began, 2)}
    return train, test, points, dataset


def run_one(train, test, points, weight: float, args) -> dict:
    """Train, decode and score one lambda."""
    color = ColorStageSettings(iterations=args.iterations, rate_weight=weight,
                               initial_anchors=args.anchors, max_anchors=args.max_anchors,
                               seed=args.seed)
    settings = TrainSettings(color, semantic_iterations=args.semantic_iterations,
                             stage3_iterations=max(1, 2 * args.semantic_iterations // 3),
                             budget_seconds=args.budget)
    cpu, wall = time.process_time(), time.perf_counter()

    def report(stage: str, step) -> None:
        if step is None:
            print(f"{stage} ({time.perf_counter() - wall:.0f} s)", file=sys.stderr)
        elif step.step % 500 == 0 or step.step == step.iterations:
            print(f"  step {step.step}/{step.iterations}: train PSNR {step.psnr:.2f} dB, "
                  f"{step.anchors} anchors, {time.perf_counter() - wall:.0f} s",
                  file=sys.stderr)

    result = train_scene(train, points, settings, progress=report)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    if not decoded.equals(result.encode.reconstruction):
        raise SystemExit("decode differs from the encoder's reconstruction")
    scores = score_views(decoded, test)
    chunks = result.encode.chunk_bytes
    layers = {name: sum(chunks.get(c, 0) for c in members)
              for name, members in LAYER_CHUNKS.items()}
    return {"lambda": weight, "anchors": len(decoded),
            "gaussian_slots": int(decoded.active_offsets()), "bytes": len(result.data),
            "layer_bytes": layers, "chunk_bytes": chunks,
            "semantic_share": layers["semantic"] / len(result.data),
            "test_psnr": scores.psnr, "test_ssim": scores.ssim, "test_views": scores.views,
            "test_psnr_foreground": (None if np.isnan(scores.foreground_psnr)
                                     else scores.foreground_psnr),
            "image_miou_vs_segmenter": image_click_miou(decoded, test),
            "stage1_steps": result.color_state.step,
            "stage_seconds": {k: round(v, 2) for k, v in result.seconds.items()},
            "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
            "peak_rss_bytes": peak_rss_bytes()}


def main() -> int:
    """Render the views, train every lambda and write the JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--capture", metavar="DIR",
                        help="a photo capture csgs train reads (instead of --scene's renders)")
    parser.add_argument("--resolution", type=int, default=384,
                        help="with --capture: the photos' longer side, pixels")
    parser.add_argument("--test-every", type=int, default=8,
                        help="with --capture: hold out every K-th photo")
    parser.add_argument("--budget", type=float, metavar="SECONDS",
                        help="plan stage 1 to fit this wall time (as csgs train --budget)")
    parser.add_argument("--scene", default="donut")
    parser.add_argument("--lambdas", type=float, nargs="+", default=list(RATE_WEIGHT_PRESETS))
    parser.add_argument("--views", type=int, default=24)
    parser.add_argument("--size", default="160x120")
    parser.add_argument("--iterations", type=int, default=2000)
    parser.add_argument("--anchors", type=int, default=2000)
    parser.add_argument("--semantic-iterations", type=int, default=SEMANTIC_ITERATIONS,
                        help="stage-2 steps (stage 3 runs two thirds as many, as in csgs "
                             "train)")
    parser.add_argument("--max-anchors", type=int,
                        help=f"default {MAX_ANCHORS} (csgs train's) with --capture, else 8000")
    parser.add_argument("--initial-points", choices=("scene", "random", "sfm"),
                        default="scene",
                        help="scene: a seeded subset of the scene's centres, standing in for "
                             "the sparse SfM points a capture comes with; random: in the "
                             "cameras' view ball; sfm: triangulated by pycolmap from the "
                             "training views")
    parser.add_argument("--points", type=int, default=5000,
                        help="initial points taken from the scene")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out")
    args = parser.parse_args()
    if args.max_anchors is None:
        args.max_anchors = MAX_ANCHORS if args.capture else 8000
    if args.capture:
        train, test, points, dataset = capture_views(args.capture, args.resolution,
                                                     args.test_every, args.seed)
        print(f"{dataset['train_views']} training views, {dataset['test_views']} held out, "
              f"{dataset['width']}x{dataset['height']}; initial points: "
              f"{dataset['initial_points']}", file=sys.stderr)
        return train_all(train, test, points, args, dataset)
    width, height = (int(v) for v in re.fullmatch(r"(\d+)x(\d+)", args.size).groups())
    began = time.perf_counter()
    scene = read_ply(SCENES / f"{args.scene}.ply")
    views = rendered_views(scene, args.views, width, height)
    render_seconds = time.perf_counter() - began
    train, test = split_views(views, 4)
    if args.initial_points == "scene":
        rng = np.random.default_rng(args.seed)
        chosen = rng.choice(len(scene), size=min(args.points, len(scene)), replace=False)
        points = scene.positions[np.sort(chosen)].astype(np.float64)
    elif args.initial_points == "sfm":
        found = triangulate_views(train)
        points = found.points
        print(f"{len(points):,} points triangulated from {len(train)} views "
              f"({'cached' if found.cached else 'new'})", file=sys.stderr)
    else:
        points = random_points([v.camera for v in train], seed=args.seed)
    return train_all(train, test, points, args,
                     {"scene": args.scene, "scene_gaussians": len(scene), "views": len(views),
                      "train_views": len(train), "test_views": len(test), "width": width,
                      "height": height, "masks": "segment_image (classical fallback)",
                      "initial_points": args.initial_points,
                      "initial_point_count": len(points),
                      "render_seconds": round(render_seconds, 2)})


def train_all(train, test, points, args, dataset: dict) -> int:
    """Train every lambda of ``args`` and write the JSON document."""
    results = []
    for weight in args.lambdas:
        results.append(run_one(train, test, points, weight, args))
        row = results[-1]
        print(f"lambda {weight}: {row['bytes']:,} bytes, {row['test_psnr']:.2f} dB, "
              f"share {100 * row['semantic_share']:.2f}%, mIoU vs segmenter "
              f"{row['image_miou_vs_segmenter']:.3f}, {row['wall_s']:.0f} s", file=sys.stderr)
    emit(document("train_real", results, settings=vars(args), dataset=dataset), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
