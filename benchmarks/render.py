"""Rasterizer speed: forward time per view (torch and numba) and torch forward+backward time.

Cases (issue 6): one 800x600 orbit view each of donut (46k), biker (153k) and playbot (248k)
with the torch reference and the numba path, after checking that the two agree; forward +
backward of the torch path for 100k Gaussians (a random subset of biker) at 400x300.
Targets on 2 cores: numba forward <= 1.0 s per view at 250k; torch forward+backward <= 2 s.

Usage: .venv/bin/python benchmarks/render.py [--out FILE] [--repeats N] [--quick]
Writes one JSON document in the csgs-bench/1 schema (see benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.render.numba_loader import numba_available
from csgs_codec.render.rasterize_torch import prepare_gaussians, rasterize_gaussians
from csgs_codec.render.rasterizer import render, scene_tensors
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene

SCENES = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "scenes"
#: Scene file, up axis of its capture (checked by looking at renders), precision kind.
VIEW_CASES = [
    ("donut.ply", (0.0, 0.0, 1.0), "full-precision"),
    ("biker.ply", (0.0, -1.0, 0.0), "re-decoded (PlayCanvas compressed PLY)"),
    ("playbot.ply", (0.0, -1.0, 0.0), "re-decoded (SOG)"),
]


def orbit_view(scene: GaussianScene, up: tuple[float, float, float], width: int, height: int,
               azimuth_deg: float = 30.0, fov_deg: float = 50.0) -> Camera:
    """A camera 1.5 extents from the robust centre, 0.4 extents above it, looking at it."""
    centre, extent = scene.robust_center_and_extent()
    up_v = np.asarray(up, np.float64)
    side = np.cross(up_v, [0.3, 0.5, 0.8])
    side /= np.linalg.norm(side)
    other = np.cross(up_v, side)
    a = np.radians(azimuth_deg)
    eye = centre + 1.5 * extent * (np.cos(a) * side + np.sin(a) * other) + 0.4 * extent * up_v
    forward = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(forward, up_v)
    right /= np.linalg.norm(right)
    rot = np.stack([right, np.cross(forward, right), forward])
    w2c = np.eye(4)
    w2c[:3, :3] = rot
    w2c[:3, 3] = -rot @ eye
    focal = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    return Camera(width, height, focal, focal, width / 2, height / 2, w2c)


@dataclass
class Timing:
    """Wall and CPU seconds of repeated calls; CPU seconds (summed over threads) and the
    fastest call help read figures taken on a shared machine."""

    median_s: float
    best_s: float
    cpu_s: float
    result: object


def timed(fn, repeats: int) -> Timing:
    """Call ``fn`` ``repeats`` times; the median and fastest wall time, median CPU time."""
    walls, cpus, result = [], [], None
    for _ in range(repeats):
        start, cpu_start = time.perf_counter(), time.process_time()
        result = fn()
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu_start)
    return Timing(statistics.median(walls), min(walls), statistics.median(cpus), result)


def machine() -> dict:
    """The machine facts the schema asks for, plus thread counts and load."""
    info = {"cpus": os.cpu_count(), "platform": platform.platform(),
            "python": sys.version.split()[0], "torch": torch.__version__,
            "torch_threads": torch.get_num_threads(),
            "load_average_1m_at_start": os.getloadavg()[0]}
    if numba_available():
        import numba

        # The kernels module picks numba's threading layer; import it before anything starts
        # numba's thread pool (an OpenMP pool started first slows torch down many times).
        from csgs_codec.render import numba_kernels  # noqa: F401

        info["numba"] = numba.__version__
        # The configured count: asking the pool itself would start it before any timing.
        info["numba_threads"] = numba.config.NUMBA_NUM_THREADS
        info["numba_threading_layer"] = numba.config.THREADING_LAYER
    return info


def view_rows(repeats: int, quick: bool) -> list[dict]:
    """Forward time per 800x600 view, torch and numba, for each shared scene."""
    rows = []
    width, height = (200, 150) if quick else (800, 600)
    for name, up, kind in VIEW_CASES:
        path = SCENES / name
        if not path.exists():
            continue
        scene = read_ply(path)
        camera = orbit_view(scene, up, width, height)
        base = {"scene": name, "scene_kind": kind, "gaussians": len(scene), "width": width,
                "height": height, "up_axis": list(up)}
        slow = timed(lambda s=scene, c=camera: render(s, c, backend="torch"), 1)
        ref = slow.result
        rows.append({**base, "backend": "torch", "forward_s": round(slow.median_s, 3),
                     "forward_cpu_s": round(slow.cpu_s, 3),
                     "foreground_fraction": round(float((ref.alpha > 0.05).mean()), 4)})
        if not numba_available():
            continue
        render(scene, orbit_view(scene, up, 64, 48), backend="numba")  # JIT / cache load
        fast = render(scene, camera, backend="numba")
        max_diff = float(np.abs(fast.image - ref.image).max())
        tensors = scene_tensors(scene)

        def prepare(t=tensors, c=camera):
            with torch.no_grad():
                return prepare_gaussians(t["means"], t["log_scales"], t["quats"],
                                         t["opacity_logits"], c, sh=t["sh"])

        prep = timed(prepare, repeats)
        fast_t = timed(lambda s=scene, c=camera: render(s, c, backend="numba"), repeats)
        rows.append({**base, "backend": "numba", "forward_s": round(fast_t.median_s, 3),
                     "forward_cpu_s": round(fast_t.cpu_s, 3),
                     "forward_best_s": round(fast_t.best_s, 3),
                     "of_which_torch_prepare_s": round(prep.median_s, 3), "repeats": repeats,
                     "max_abs_diff_vs_torch": max_diff,
                     "pixels_over_1e-4": int((np.abs(fast.image - ref.image) > 1e-4).sum())})
    return rows


def forward_backward_row(repeats: int, quick: bool, checkpointed: bool | None) -> dict | None:
    """Torch forward + backward for 100k Gaussians of biker at 400x300.

    ``checkpointed`` None is the default policy (store bands up to a pair budget, recompute
    the rest); True recomputes every band in the backward pass (least memory).
    """
    from csgs_codec.render import composite_torch

    path = SCENES / "biker.ply"
    if not path.exists():
        return None
    scene = read_ply(path)
    count = 10_000 if quick else 100_000
    scene = scene.subset(np.sort(np.random.default_rng(0).permutation(len(scene))[:count]))
    width, height = (200, 150) if quick else (400, 300)
    camera = orbit_view(scene, (0.0, -1.0, 0.0), width, height)
    base = scene_tensors(scene)
    defaults = composite_torch.composite.__kwdefaults__
    saved = defaults["checkpointed"]
    defaults["checkpointed"] = checkpointed

    def step():
        params = {k: v.clone().requires_grad_() for k, v in base.items()}
        out = rasterize_gaussians(**params, camera=camera)
        loss = out.image.sum() + out.alpha.sum()
        loss.backward()
        return params

    try:
        timing = timed(step, repeats)
    finally:
        defaults["checkpointed"] = saved
    grads_finite = all(bool(torch.isfinite(p.grad).all()) for p in timing.result.values())
    return {"case": "forward_backward", "scene": "biker.ply", "scene_kind": VIEW_CASES[1][2],
            "gaussians": count, "width": width, "height": height, "backend": "torch",
            "checkpointing": {None: "default", True: "every band"}[checkpointed],
            "forward_backward_s": round(timing.median_s, 3),
            "forward_backward_cpu_s": round(timing.cpu_s, 3),
            "forward_backward_best_s": round(timing.best_s, 3),
            "repeats": repeats, "gradients_finite": grads_finite}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and write the JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write JSON here instead of stdout")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="small sizes, for a smoke run")
    parser.add_argument("--torch-threads", type=int, help="torch.set_num_threads before timing")
    args = parser.parse_args(argv)
    if args.torch_threads:
        torch.set_num_threads(args.torch_threads)
    info = machine()
    results = []
    for checkpointed in (None, True):
        row = forward_backward_row(args.repeats, args.quick, checkpointed)
        if row is not None:
            results.append(row)
    results += view_rows(args.repeats, args.quick)
    info["load_average_1m_at_end"] = os.getloadavg()[0]
    doc = {"schema": "csgs-bench/1", "benchmark": "render", "machine": info,
           "results": results}
    text = json.dumps(doc, indent=2)
    if args.out:
        args.out.write_text(text + "\n")
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
