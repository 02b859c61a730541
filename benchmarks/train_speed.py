"""Training speed: stage-1 steps per second and the semantic stage's time on one device.

    python benchmarks/train_speed.py [--device cpu|cuda] [--size 512x384] [--steps 60]
        [--anchors 2000] [--offsets 10] [--semantic-iterations 40] [--out FILE]

Stage 1 (csgs_codec/train/color_stage.py) runs ``--steps`` steps on a seeded synthetic
dataset (5 objects x 1,500 Gaussians, 24 views at ``--size``) from about ``--anchors``
anchors with ``--offsets`` Gaussian slots each (2,000 x 10: about 20k slots), growth off so
the slot count holds; the first 5 steps are a warm-up left out of the rate. The semantic
stage (csgs_codec/train/semantic_stage.py) trains ``--semantic-iterations`` steps on a small
scene (3 objects x 50 Gaussians, 3 views at 32x24: the gpu test's case). The JSON (schema
csgs-bench/1) has the device, steps/s, seconds, and on CUDA the peak GPU memory.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_common import document, emit  # noqa: E402

WARMUP = 5


def stage_one_speed(device: str, width: int, height: int, steps: int, anchors: int,
                    offsets: int) -> dict:
    """Steps/s of stage 1 after a warm-up, and the Gaussian slots trained."""
    import torch

    from csgs_codec.train.color_stage import (
        ColorStageSettings,
        initial_state,
        train_color_stage,
    )
    from csgs_codec.train.synthetic import make_synthetic_dataset

    data = make_synthetic_dataset(0, objects=5, gaussians_per_object=1500, views=24,
                                  width=width, height=height)
    settings = ColorStageSettings(iterations=WARMUP + steps, initial_anchors=anchors,
                                  max_anchors=anchors, n_offsets=offsets, growth_start=1.0,
                                  growth_end=1.0, device=device)
    state = initial_state(data.views, data.scene.positions, settings)
    slots = int(state.model.cells.shape[0]) * offsets
    times = []

    def tick(*_args, **_kwargs) -> None:
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        times.append(time.perf_counter())

    start = time.perf_counter()
    train_color_stage(data.views, state, progress=tick)
    total = time.perf_counter() - start
    timed = times[WARMUP:] if len(times) > WARMUP + 1 else times
    rate = (len(timed) - 1) / (timed[-1] - timed[0]) if len(timed) > 1 else None
    return {"steps": WARMUP + steps, "seconds": total, "steps_per_s": rate,
            "gaussian_slots": slots, "size": f"{width}x{height}"}


def semantic_stage_time(device: str, iterations: int) -> dict:
    """Seconds of the semantic stage on the gpu test's small case."""
    from csgs_codec.train.semantic_stage import prepare_semantic_views, train_semantic_features
    from csgs_codec.train.synthetic import make_synthetic_dataset

    dataset = make_synthetic_dataset(11, objects=3, gaussians_per_object=50, views=3,
                                     width=32, height=24)
    views = prepare_semantic_views(dataset.scene, dataset.views)
    start = time.perf_counter()
    train_semantic_features(views, len(dataset.scene), iterations=iterations, seed=4,
                            device=device)
    return {"iterations": iterations, "seconds": time.perf_counter() - start}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--size", default="512x384")
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--anchors", type=int, default=2000)
    parser.add_argument("--offsets", type=int, default=10)
    parser.add_argument("--semantic-iterations", type=int, default=40)
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    import torch

    width, height = (int(v) for v in args.size.split("x"))
    row = {"device": args.device, "torch": torch.__version__}
    if args.device.startswith("cuda"):
        row["gpu"] = torch.cuda.get_device_name()
        torch.cuda.reset_peak_memory_stats()
    row["stage1"] = stage_one_speed(args.device, width, height, args.steps, args.anchors,
                                    args.offsets)
    row["semantic_stage"] = semantic_stage_time(args.device, args.semantic_iterations)
    if args.device.startswith("cuda"):
        row["peak_gpu_bytes"] = torch.cuda.max_memory_allocated()
    print(f"{args.device}: stage 1 {row['stage1']['steps_per_s']} steps/s, semantic stage "
          f"{row['semantic_stage']['seconds']:.1f} s", file=sys.stderr)
    emit(document("train_speed", [row]), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
