"""Training speed: stage-1 steps per second and the semantic stage's time on one device.

    python benchmarks/train_speed.py [--device cpu|cuda] [--rasterizer auto|torch|gsplat]
        [--size 512x384] [--steps 60] [--anchors 2000] [--offsets 10]
        [--gaussians-per-object 1500] [--views 24] [--semantic-iterations 40] [--out FILE]

Stage 1 (csgs_codec/train/color_stage.py) runs ``--steps`` steps on a seeded synthetic
dataset (5 objects x ``--gaussians-per-object`` Gaussians, ``--views`` views at ``--size``)
from about ``--anchors`` anchors with ``--offsets`` Gaussian slots each (2,000 x 10: about
20k slots), growth off so the slot count holds, through ``--rasterizer`` (auto: gsplat on
CUDA when installed); the first 5 steps are a warm-up left out of the rate and out of
``cpu_s_per_step``, the process's CPU seconds a timed step (every thread: on a machine other
work shares it moves less than the wall-clock rate does). The semantic
stage (csgs_codec/train/semantic_stage.py) trains ``--semantic-iterations`` steps on a small
scene (3 objects x 50 Gaussians, 3 views at 32x24: the gpu test's case). The JSON (schema
csgs-bench/1) has the device, steps/s, seconds, and on CUDA the peak GPU memory.

``--count-ops N`` adds ``stage1_ops``: the torch operators one stage-1 step dispatches
(forward and backward, views left out, so about one kernel launch each on a GPU), averaged
over N steps after the timed ones and split by the part of the step that issued them
(rasterizer, rate model, Scaffold-GS heads, loss, optimiser, growth statistics, the step's
own bookkeeping). On CUDA training is bound by launching those operators (about 630 a
step against 2.5 ms of device work in 19 ms measured on an H100), so the count measured on
any machine tracks the GPU's step time where no GPU is at hand.
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
                    offsets: int, *, rasterizer: str = "auto", gaussians_per_object: int = 1500,
                    views: int = 24, profile_steps: int = 0, profile_out: str | None = None,
                    count_ops: int = 0, all_slots: bool | None = None
                    ) -> tuple[dict, dict | None]:
    """Steps/s of stage 1 after a warm-up, and the Gaussian slots trained; with
    ``profile_steps`` > 0, that many more steps run under torch.profiler and its table (ops
    by self CPU time, then by device time) goes to ``profile_out``; with ``count_ops`` > 0,
    that many more steps run under :func:`count_step_ops` (its result is the second item)."""
    import torch

    from csgs_codec.render.differentiable import resolve_training_rasterizer
    from csgs_codec.train.color_stage import (
        ColorStageSettings,
        initial_state,
        train_color_stage,
    )
    from csgs_codec.train.synthetic import make_synthetic_dataset

    data = make_synthetic_dataset(0, objects=5, gaussians_per_object=gaussians_per_object,
                                  views=views, width=width, height=height)
    settings = ColorStageSettings(iterations=WARMUP + steps + profile_steps + count_ops,
                                  initial_anchors=anchors,
                                  max_anchors=anchors, n_offsets=offsets, growth_start=1.0,
                                  growth_end=1.0, device=device, rasterizer=rasterizer,
                                  # older code, measured with this script, lacks the field
                                  **({} if all_slots is None else {"all_slots": all_slots}))
    state = initial_state(data.views, data.scene.positions, settings)
    slots = int(state.model.cells.shape[0]) * offsets
    times, cpu_times = [], []

    def tick(*_args, **_kwargs) -> None:
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        times.append(time.perf_counter())
        cpu_times.append(time.process_time())

    start = time.perf_counter()
    train_color_stage(data.views, state, progress=tick, stop_at=WARMUP + steps)
    total = time.perf_counter() - start
    if profile_steps > 0 and profile_out:
        write_profile(lambda: train_color_stage(data.views, state,
                                                stop_at=WARMUP + steps + profile_steps),
                      device, profile_out)
    ops = None
    if count_ops > 0:
        ops = count_step_ops(lambda: train_color_stage(data.views, state), count_ops)
    timed = times[WARMUP:] if len(times) > WARMUP + 1 else times
    rate = (len(timed) - 1) / (timed[-1] - timed[0]) if len(timed) > 1 else None
    cpu = cpu_times[WARMUP:] if len(cpu_times) > WARMUP + 1 else cpu_times
    cpu_per_step = (cpu[-1] - cpu[0]) / (len(cpu) - 1) if len(cpu) > 1 else None
    return {"steps": WARMUP + steps, "seconds": total, "steps_per_s": rate,
            "cpu_s_per_step": cpu_per_step,
            "gaussian_slots": slots, "size": f"{width}x{height}",
            "rasterizer": resolve_training_rasterizer(rasterizer, device),
            "all_slots": all_slots}, ops


#: First matching path fragment of the issuing frame -> the part of the step it belongs to.
OP_PARTS = (("csgs_codec/render/", "rasterizer"), ("gsplat/", "rasterizer"),
            ("csgs_codec/train/anchor_rate.py", "rate"),
            ("csgs_codec/train/quantization.py", "rate"),
            ("csgs_codec/model/scaffold.py", "scaffold"),
            ("csgs_codec/train/anchor_model.py", "scaffold"),
            ("csgs_codec/metrics/", "loss"), ("csgs_codec/train/losses.py", "loss"),
            ("csgs_codec/train/anchor_growth.py", "growth_stats"),
            ("torch/optim/", "optimizer"), ("torch/nn/utils/clip_grad", "optimizer"),
            ("csgs_codec/train/grouped_adam.py", "optimizer"),
            ("csgs_codec/train/color_stage.py", "step"))


def _part_of(frames) -> str:
    """The part of the step the innermost recognised frame of ``frames`` belongs to."""
    for filename in reversed(frames):
        for fragment, part in OP_PARTS:
            if fragment in filename:
                return part
    return "other"


def count_step_ops(run, steps: int) -> dict:
    """Operators dispatched per step while ``run()`` trains ``steps`` steps: total and by
    part (see the module notes). Backward operators are charged to the forward code that
    recorded them (anomaly mode keeps its stack)."""
    import traceback
    from collections import Counter

    import torch
    from torch.utils._python_dispatch import TorchDispatchMode

    aten = torch.ops.aten
    no_kernel = {aten.detach.default, aten.lift_fresh.default, aten._local_scalar_dense.default,
                 aten.empty.memory_format, aten.empty_strided.default, aten.empty_like.default}

    class Counting(TorchDispatchMode):
        def __init__(self) -> None:
            super().__init__()
            self.parts: Counter = Counter()

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):
            out = func(*args, **(kwargs or {}))
            if func.is_view or func in no_kernel:
                return out
            node = torch._C._current_autograd_node()
            if node is not None:
                trace = node.metadata.get("traceback_", [])
                frames = [line.split('"')[1] for line in trace if line.count('"') >= 2]
                self.parts["backward:" + _part_of(frames)] += 1
            else:
                frames = [frame.filename for frame in traceback.extract_stack()[:-1]]
                self.parts["forward:" + _part_of(frames)] += 1
            return out

    counting = Counting()
    try:
        with counting, torch.autograd.detect_anomaly(check_nan=False):
            run()
    except Exception as error:  # a count that fails must not cost the timed figures
        return {"steps": steps, "error": f"{type(error).__name__}: {error}"}
    by_part: Counter = Counter()
    for key, count in counting.parts.items():
        by_part[key.split(":", 1)[1]] += count
    total = sum(counting.parts.values())
    return {"steps": steps, "per_step": total / steps,
            "forward_per_step": sum(v for k, v in counting.parts.items()
                                    if k.startswith("forward")) / steps,
            "by_part": {k: v / steps for k, v in sorted(by_part.items())}}


def write_profile(run, device: str, path: str) -> None:
    """Run ``run()`` under torch.profiler and write its op tables (self CPU time, then
    device time; 40 rows each) to ``path``."""
    import torch
    from torch.profiler import ProfilerActivity, profile

    activities = [ProfilerActivity.CPU]
    if device.startswith("cuda"):
        activities.append(ProfilerActivity.CUDA)
    with profile(activities=activities) as prof:
        run()
        if device.startswith("cuda"):
            torch.cuda.synchronize()
    table = prof.key_averages()
    parts = [table.table(sort_by="self_cpu_time_total", row_limit=40)]
    if device.startswith("cuda"):
        parts.append(table.table(sort_by="self_cuda_time_total", row_limit=40))
    with open(path, "w", encoding="utf-8") as handle:
        handle.write("\n\n".join(parts))


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
    parser.add_argument("--rasterizer", default="auto", choices=("auto", "torch", "gsplat"))
    parser.add_argument("--gaussians-per-object", type=int, default=1500)
    parser.add_argument("--views", type=int, default=24)
    parser.add_argument("--semantic-iterations", type=int, default=40)
    parser.add_argument("--profile-steps", type=int, default=0,
                        help="steps after the timed ones to run under torch.profiler")
    parser.add_argument("--profile-out", help="where the profiler's tables go")
    parser.add_argument("--code", help="which code this row measures (a label)")
    parser.add_argument("--count-ops", type=int, default=0,
                        help="steps after those to count dispatched operators over")
    parser.add_argument("--all-slots", choices=("auto", "yes", "no"), default="auto",
                        help="spawn every anchor slot (default: with gsplat)")
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    import torch

    width, height = (int(v) for v in args.size.split("x"))
    row = {"device": args.device, "torch": torch.__version__}
    if args.code:
        row["code"] = args.code
    if args.device.startswith("cuda"):
        row["gpu"] = torch.cuda.get_device_name()
        torch.cuda.reset_peak_memory_stats()
    row["stage1"], ops = stage_one_speed(args.device, width, height, args.steps, args.anchors,
                                    args.offsets, rasterizer=args.rasterizer,
                                    gaussians_per_object=args.gaussians_per_object,
                                    views=args.views, profile_steps=args.profile_steps,
                                    profile_out=args.profile_out, count_ops=args.count_ops,
                                    all_slots={"auto": None, "yes": True,
                                               "no": False}[args.all_slots])
    if ops is not None:
        row["stage1_ops"] = ops
    if args.semantic_iterations > 0:
        row["semantic_stage"] = semantic_stage_time(args.device, args.semantic_iterations)
    if args.device.startswith("cuda"):
        row["peak_gpu_bytes"] = torch.cuda.max_memory_allocated()
    semantic = row.get("semantic_stage", {}).get("seconds")
    print(f"{args.device} ({row['stage1']['rasterizer']}): stage 1 "
          f"{row['stage1']['steps_per_s']} steps/s with {row['stage1']['gaussian_slots']} "
          f"slots at {args.size}; semantic stage {semantic} s", file=sys.stderr)
    emit(document("train_speed", [row]), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
