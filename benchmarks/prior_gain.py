"""Does the color hyperprior earn its place? Color-layer bits of the same quantization under
three entropy models, and what the hyperprior costs in time.

    .venv/bin/python benchmarks/prior_gain.py [--scenes donut plant biker guitar playbot]
        [--qualities 2 5 8] [--out FILE]

For each scene and preset the quantized color attributes are identical in all three (the
hyperprior changes the rate only; the script checks that the decodes match):

- ``factorized``: every coded channel with its own best single frozen Gaussian table or its
  own frequency table (modes 1 and 4 without channel prediction): a per-attribute factorized
  model;
- ``plain``: the encoder without the hyperprior (adds the channel-wise linear prediction);
- ``hyperprior``: the default encoder (channel prediction plus the INR hyperprior where it
  pays, the CHYP network's bytes included).

Reports color-layer bits per Gaussian of each, their ratios, whole-file sizes, the fit's
share of the encode time and decode times with and without the hyperprior.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import SCENES, document, emit  # noqa: E402

from csgs_codec import read_ply  # noqa: E402
from csgs_codec.attributes.float_stream import plan_float_stream  # noqa: E402
from csgs_codec.attributes.streams import split_streams  # noqa: E402
from csgs_codec.chunks.color_streams import STREAM_CHUNKS  # noqa: E402
from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import preset  # noqa: E402
from csgs_codec.entropy.histogram import histogram_cost  # noqa: E402
from csgs_codec.entropy.residual import quantize, to_grid  # noqa: E402
from csgs_codec.entropy.table_choice import table_costs  # noqa: E402

COLOR_CHUNKS = set(STREAM_CHUNKS.values()) | {"CHYP"}


def factorized_bits(reconstruction, settings) -> float:
    """Bits of the color streams of ``reconstruction`` (already in decoded order and on the
    grid) with one table per channel and no prediction, plus 3 bytes of header per channel."""
    streams = split_streams(reconstruction).float_streams
    steps = {"dc": settings.dc_step, "rest1": settings.rest_step, "rest2": settings.rest_step,
             "rest3": settings.rest_step, "opacity": settings.opacity_step,
             "scale": settings.scale_step, "rot": settings.rotation_step}
    total = 0.0
    for name, values in streams.items():
        plan = plan_float_stream(values, steps[name])
        for c, channel in enumerate(plan.channels):
            if channel.is_constant:
                continue
            grid = to_grid(values[:, c].astype(np.float64), plan.frac_bits)
            k = quantize(grid, np.full(len(grid), channel.mean, np.int64),
                         np.full(len(grid), plan.step_idx, np.int64))
            total += min(float(table_costs(k).min()), histogram_cost(k)) + 24
    return total


def color_bits(result) -> float:
    """Color-layer payload bits of an encode."""
    return 8.0 * sum(v for k, v in result.stream_bytes.items() if k in COLOR_CHUNKS)


def _timed_decode(data: bytes) -> tuple[float, object]:
    start = time.perf_counter()
    scene = Decoder().decode(data)
    return time.perf_counter() - start, scene


def run_scene(name: str, qualities: list[int]) -> list[dict]:
    """One row per preset for scene ``name``."""
    scene = read_ply(SCENES / f"{name}.ply")
    n = len(scene)
    rows = []
    for q in qualities:
        plain = Encoder(quality=q, hyperprior=False).encode_with_report(scene)
        prior = Encoder(quality=q).encode_with_report(scene)
        plain_decode, plain_scene = _timed_decode(plain.data)
        prior_decode, prior_scene = _timed_decode(prior.data)
        for attr, value in prior_scene.attributes().items():
            other = plain_scene.attributes()[attr]
            if value is not None and not np.array_equal(value, other):
                raise SystemExit(f"{name} q{q}: {attr} differs with the hyperprior")
        # The plain encode's reconstruction is on the grid already: re-quantizing it with
        # the same steps gives back the same indices, so the factorized model codes exactly
        # the same quantization.
        factorized = factorized_bits(plain.reconstruction, preset(q))
        row = {
            "scene": name, "quality": q, "gaussians": n,
            "color_bits_per_gaussian": {
                "factorized": factorized / n, "plain": color_bits(plain) / n,
                "hyperprior": color_bits(prior) / n},
            "chyp_bytes": prior.stream_bytes.get("CHYP", 0),
            "file_bits_per_gaussian": {"plain": 8 * len(plain.data) / n,
                                       "hyperprior": 8 * len(prior.data) / n},
            "ratio_hyperprior_to_factorized": color_bits(prior) / factorized,
            "ratio_hyperprior_to_plain": color_bits(prior) / color_bits(plain),
            "ratio_plain_to_factorized": color_bits(plain) / factorized,
            "encode_s": {"plain": plain.seconds, "hyperprior": prior.seconds},
            "decode_s": {"plain": plain_decode, "hyperprior": prior_decode},
        }
        rows.append(row)
        bits = row["color_bits_per_gaussian"]
        print(f"{name} q{q}: color bits/G factorized {bits['factorized']:.2f} plain "
              f"{bits['plain']:.2f} hyperprior {bits['hyperprior']:.2f} "
              f"(x{row['ratio_hyperprior_to_factorized']:.3f} of factorized, "
              f"x{row['ratio_hyperprior_to_plain']:.3f} of plain); encode {plain.seconds:.1f}"
              f" / {prior.seconds:.1f} s, decode {plain_decode:.2f} / {prior_decode:.2f} s",
              flush=True)
    return rows


def main() -> None:
    """Parse arguments, run every scene and preset, write the JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["donut", "plant", "biker", "guitar",
                                                         "playbot"])
    parser.add_argument("--qualities", nargs="+", type=int, default=[2, 5, 8])
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    results = []
    for name in args.scenes:
        results += run_scene(name, args.qualities)
    emit(document("prior_gain", results, qualities=args.qualities), args.out)


if __name__ == "__main__":
    main()
