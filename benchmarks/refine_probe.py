"""First measurement of ``--refine N`` (issue 17 item 5): dB gained at equal bits per CPU-minute.

Refinement optimises the pre-quantization attributes so that the *decoded* scene renders like
the original: N Adam steps on the coding-form DC colour, opacity logits, log-scales and
smallest-three rotation components (positions stay on their decoded grid), each step on 2
random views of the default viewing distribution rendered at ``--size`` with the
differentiable torch rasterizer, with straight-through rounding on the codec's own lattice
(the base encode's frac bits, channel means and step, so that what is optimised is what the
decoder will output). The learning rate is ``--lr`` times each attribute's step.

Bits are the file's plus the change of the re-quantized streams' estimated size (the codec's
planner cost, same lattice); PSNR is the foreground PSNR on held-out views never used for
allocation or refinement (16 orbit views at 20 degrees + 12 at 45 degrees, 800x600);
``ratio_vs_presets`` compares with the uniform presets' curve at the same PSNR.

    .venv/bin/python benchmarks/refine_probe.py donut --quality 5 --steps 20 60 --out r.json
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import FULL_PRECISION, SCENES, document, emit  # noqa: E402
from derived_steps import STEP_NAMES, HeldOut, size_at_psnr  # noqa: E402

from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.codec.float_stream import _fit_prediction, frac_bits_for, predict  # noqa: E402
from csgs_codec.codec.presets import preset  # noqa: E402
from csgs_codec.codec.streams import SceneStreams, join_streams, split_streams  # noqa: E402
from csgs_codec.entropy.histogram import histogram_cost  # noqa: E402
from csgs_codec.entropy.residual import (  # noqa: E402
    from_grid,
    quantize,
    reconstruct,
    step_index,
    step_size,
    to_grid,
)
from csgs_codec.entropy.table_choice import table_costs  # noqa: E402
from csgs_codec.render.cameras_io import resize_camera  # noqa: E402
from csgs_codec.render.rasterize_torch import rasterize_gaussians  # noqa: E402
from csgs_codec.render.rasterizer import scene_tensors  # noqa: E402
from csgs_codec.render.view_distribution import default_distribution  # noqa: E402
from csgs_codec.scene.ply_io import read_ply  # noqa: E402

REFINED = ("dc", "opacity", "scale", "rot")


@dataclasses.dataclass(frozen=True)
class Lattice:
    """One stream's quantization lattice: frac bits, step index and integer step, means."""

    frac_bits: int
    step_idx: int
    step: int
    means: np.ndarray

    @classmethod
    def of(cls, values: np.ndarray, step: float) -> Lattice:
        """The lattice the codec's planner puts ``values`` (N, C) on at ``step``."""
        f = frac_bits_for(values)
        idx = int(step_index(np.array([step * 2.0 ** f]))[0])
        means = [int(np.rint(np.median(to_grid(values[:, c].astype(np.float64), f))))
                 for c in range(values.shape[1])]
        return cls(f, idx, int(step_size(np.array([idx]))[0]), np.array(means, np.int64))

    def round_through(self, x: torch.Tensor) -> torch.Tensor:
        """Decoded values of ``x`` (N, C) in the forward pass, identity gradient."""
        scale = 2.0 ** self.frac_bits
        grid = torch.round(x.double() * scale)
        mu = torch.as_tensor(self.means, dtype=torch.float64)
        k = torch.floor((2 * (grid - mu) + self.step) / (2 * self.step))
        value = ((mu + self.step * k) / scale).to(x.dtype)
        return x + (value - x).detach()

    def cost(self, values: np.ndarray) -> tuple[float, np.ndarray]:
        """(estimated bits, decoded (N, C) float32) of ``values`` on this lattice."""
        n, channels = values.shape
        steps = np.full(n, self.step_idx, np.int64)
        indices = np.zeros((channels, n), np.int64)
        recon = np.empty((n, channels), np.float32)
        total = 0.0
        for c in range(channels):
            grid = to_grid(values[:, c].astype(np.float64), self.frac_bits)
            mean = np.full(n, self.means[c], np.int64)
            k = quantize(grid, mean, steps)
            indices[c] = k
            costs = [float(table_costs(k).min()), histogram_cost(k)]
            fitted = _fit_prediction(indices[:c].T, k)
            if fitted is not None:
                r = k - predict(indices[:c], *fitted)
                costs += [float(table_costs(r).min()) + 8 * (3 * c + 6),
                          histogram_cost(r) + 8 * (3 * c + 6)]
            total += min(costs) + 40
            recon[:, c] = from_grid(reconstruct(mean, k, steps), self.frac_bits)
        return total, recon


def quaternions(axis: torch.Tensor, rest: torch.Tensor) -> torch.Tensor:
    """(N, 4) quaternions from smallest-three components (N, 3) and dropped index (N,)."""
    t = rest / np.float32(np.sqrt(2.0))
    w = torch.sqrt(torch.clamp(1 - (t * t).sum(1), min=1e-12))
    n = rest.shape[0]
    columns = torch.arange(4)[None, :].expand(n, 4)
    others = columns[columns != axis[:, None]].reshape(n, 3)
    out = torch.zeros((n, 4), dtype=rest.dtype).scatter(1, axis[:, None], w[:, None])
    return out.scatter(1, others, t)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--quality", type=int, default=5)
    parser.add_argument("--steps", nargs="+", type=int, default=[20, 60])
    parser.add_argument("--size", type=int, default=400, help="refinement view width")
    parser.add_argument("--lr", type=float, default=0.02)
    parser.add_argument("--curve", default=None,
                        help="JSON rows of derived_steps.py for the uniform presets' curve")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    scene = read_ply(SCENES / f"{args.scene}.ply")
    held = HeldOut(scene)
    curve = []
    if args.curve:
        import json

        doc = json.loads(Path(args.curve).read_text())
        curve = [(r["held_out_fg_psnr_db"], r["bytes"]) for r in doc["results"]
                 if r["scene"] == f"{args.scene}.ply" and r["variant"] == "uniform"]
    result = Encoder(quality=args.quality, hyperprior=False).encode_with_report(scene)
    ordered = scene.subset(result.order)
    streams = split_streams(ordered)
    p = preset(args.quality)
    lattices = {s: Lattice.of(streams.float_streams[s], getattr(p, STEP_NAMES[s]))
                for s in REFINED}
    views = [dataclasses.replace(resize_camera(c, args.size, args.size * 3 // 4),
                                 near_plane=c.near_plane)
             for c in default_distribution(scene).cameras]
    original = scene_tensors(ordered)
    with torch.no_grad():
        targets = [rasterize_gaussians(original["means"], original["log_scales"],
                                       original["quats"], original["opacity_logits"], v,
                                       sh=original["sh"], near_plane=v.near_plane).image
                   for v in views]
    means = torch.as_tensor(result.reconstruction.positions)
    axis = torch.as_tensor(streams.rot_axis.astype(np.int64))
    params = {s: torch.nn.Parameter(torch.as_tensor(streams.float_streams[s].copy()))
              for s in REFINED}
    optimiser = torch.optim.Adam([{"params": [params[s]],
                                   "lr": args.lr * getattr(p, STEP_NAMES[s])} for s in REFINED])
    rng = np.random.default_rng(0)

    def decoded_scene():
        values = {s: params[s].detach().numpy().astype(np.float32) for s in REFINED}
        values["rot"] = np.clip(values["rot"], -1, 1)
        bits, streams_out = 0.0, dict(streams.float_streams)
        for s in REFINED:
            b, streams_out[s] = lattices[s].cost(values[s])
            bits += b
        decoded = join_streams(SceneStreams(streams_out, streams.rot_axis,
                                            streams.sh_degree_stored),
                               result.reconstruction.positions)
        return bits, decoded

    base_bits, base_scene = decoded_scene()
    if not base_scene.equals(result.reconstruction):
        raise SystemExit("the lattice does not reproduce the codec's reconstruction")
    base_psnr = held.psnr(result.reconstruction)
    row0 = {"scene": f"{args.scene}.ply", "full_precision": args.scene in FULL_PRECISION,
            "quality": args.quality, "refine_steps": 0, "bytes": len(result.data),
            "held_out_fg_psnr_db": base_psnr, "cpu_s": 0.0}
    rows = [row0]
    done, cpu = 0, 0.0
    for target in sorted(args.steps):
        start = time.process_time()
        while done < target:
            optimiser.zero_grad()
            loss = 0.0
            for v in rng.choice(len(views), 2, replace=False):
                dc = lattices["dc"].round_through(params["dc"])
                opacity = lattices["opacity"].round_through(params["opacity"])[:, 0]
                scales = lattices["scale"].round_through(params["scale"])
                rot = lattices["rot"].round_through(torch.clamp(params["rot"], -1, 1))
                image = rasterize_gaussians(means, scales, quaternions(axis, rot), opacity,
                                            views[v], sh=dc[:, None, :],
                                            near_plane=views[v].near_plane).image
                loss = loss + torch.mean((image - targets[v]) ** 2)
            loss.backward()
            optimiser.step()
            done += 1
        cpu += time.process_time() - start
        bits, decoded = decoded_scene()
        nbytes = len(result.data) + (bits - base_bits) / 8
        psnr = held.psnr(decoded)
        rows.append({**row0, "refine_steps": done, "bytes": nbytes,
                     "held_out_fg_psnr_db": psnr, "cpu_s": cpu, "delta_db": psnr - base_psnr,
                     "bytes_vs_uniform": nbytes / len(result.data),
                     "ratio_vs_presets": (nbytes / size_at_psnr(curve, psnr)) if curve
                     else None,
                     "db_per_cpu_minute": (psnr - base_psnr) / (cpu / 60)})
        print(rows[-1], file=sys.stderr)
    emit(document("refine_probe", rows, refinement_views=f"default sphere at {args.size}px",
                  held_out_views="16 @20deg + 12 @45deg, 800x600", lr_times_step=args.lr),
         args.out)


if __name__ == "__main__":
    main()
