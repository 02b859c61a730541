"""A per-scene vector codebook for the SH bands against scalar coding, at equal render PSNR
(issue 32, item 3).

    .venv/bin/python benchmarks/sh_vector_codebook.py SCENE.ply [--qualities 3 5 7]
        [--ks 64 256 1024 4096] [--kinds vq45 vq15] [--residual-ks 256 1024]
        [--residual-scales 1 2] [--rest-scales 0.5 2 4] [--subset N] [--size 400x300]
        [--out FILE]
    .venv/bin/python benchmarks/sh_vector_codebook.py ../shared/data/scenes/playbot.ply \
        --subset 32768 --rest-scales 0.5 2 --residual-ks 1024 --residual-scales 2

An experiment, not a codec feature. Every quality takes the default encode (its bytes, its
reconstruction); the preset curve is the default encodes at qualities 2..9 (``--curve``),
all scored on held-out views (16 orbit views at 20 degrees + 12 at 45, at ``--size``, none
used by the encoder). A VQ row keeps that reconstruction for everything but the SH bands
(f_rest), which it replaces by a vector-quantized copy of the *input* bands (in the
decoder's order):

- ``vq45_K``: k-means (numpy, seed 0, unweighted, started from K random input vectors,
  ``--iters`` Lloyd iterations) of each Gaussian's whole rest vector (45 floats at SH-3, 24
  at SH-2, the name kept);
- ``vq15_K``: one codebook shared by the three colours' 15-float (8 at SH-2) vectors, three
  indices per Gaussian;
- a K above half the vectors it would code is skipped;
- ``..._resS``: a scalar stage on the VQ residual, each band with S times the step the
  default encoder used for it at that quality (the preset's, after its step allocation),
  rounded to nearest.

Two controls at each quality: ``scalar_rest_xS`` re-encodes with the preset's SH-band step
times S (``--rest-scales``; scalar coding at lower SH fidelity, a real file), and
``no_sh_bands`` drops the bands (the reconstruction with zero f_rest, the file without its
SH chunks): a codebook pays only where it beats both at equal PSNR.
``ratio_vs_scalar_sh_curve`` is a row's bytes over what the curve of these scalar points at
its quality (``scalar``, each ``scalar_rest_xS`` and ``no_sh_bands``, those no other of them
beats on both size and PSNR) needs for its PSNR, the same interpolation: the codebook against
scalar SH coding with the rest of the scene (nearly) fixed. ``ratio_vs_scalar_envelope`` does
the same against every scalar point of the scene (all qualities, every SH step scale, no SH):
the preset curve is not convex on these scenes (the step allocation), so this is the ratio to
trust. ``--rescore`` recomputes these ratios of a result file in place.

Costs are an ideal adaptive coder's, counted in full (no codec tables): the codebook's
entries sit on a grid of ``--codebook-step`` times the band's scalar step, each band's
integers coded by one adaptive (Krichevsky-Trofimov) model over the codebook; the indices
(one model per colour for vq15) and the residual integers (one model per channel) by the
same estimator, which includes learning the model; every model adds 32 bits for its
alphabet range. ``index_bits_order0`` (N x H) is the index cost without learning, for
reference. The file the row stands for is the default encode's bytes less its SH band chunks
(SHBA-SHBC and SHXF) plus the VQ bits / 8.

``vq45_K*_coded`` rows (``--coded-ks``, K <= 255) write the whole-vector codebook and the
indices with the codec's own coders instead (float streams per band, a categorical stream
with its table): their cost is bytes, and their PSNR is that of the decoded codebook.

``ratio_vs_presets`` is the row's bytes over what the preset curve needs for its PSNR (log-size
linear in PSNR; null outside the curve): below 1 the codebook pays. The default rows carry
theirs too (near 1; not exactly, the curve interpolates between presets).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from math import lgamma, log
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402
from derived_steps import HeldOut, size_at_psnr  # noqa: E402

from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import PRESETS, preset, preset_steps  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402
from csgs_codec.scene.gaussian_scene import SH_REST_COUNTS  # noqa: E402

SH_CHUNKS = ("SHBA", "SHBB", "SHBC", "SHXF")
RANGE_BITS = 32  # an adaptive model's alphabet (its lowest and highest integer)


def adaptive_bits(symbols: np.ndarray) -> float:
    """Bits of an adaptive (KT, a = 1/2) coder of integer ``symbols`` over their range."""
    symbols = np.asarray(symbols).ravel()
    if symbols.size == 0:
        return 0.0
    counts = np.bincount(symbols - symbols.min())
    a, size = 0.5, counts.size
    nats = (lgamma(symbols.size + a * size) - lgamma(a * size)
            - sum(lgamma(c + a) - lgamma(a) for c in counts[counts > 0]))
    return nats / log(2.0) + RANGE_BITS


def order0_bits(symbols: np.ndarray) -> float:
    """N x H of ``symbols`` (order-0 empirical entropy, no model cost)."""
    _, counts = np.unique(symbols, return_counts=True)
    p = counts / counts.sum()
    return float(-(counts * np.log2(p)).sum())


def nearest(x: np.ndarray, codebook: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(index, squared distance) of the nearest codebook row to each row of ``x``."""
    norms = np.einsum("kd,kd->k", codebook, codebook)
    chunk = max(1, (1 << 24) // max(len(codebook), 1))
    index = np.empty(len(x), np.int64)
    dist = np.empty(len(x), np.float64)
    for lo in range(0, len(x), chunk):
        part = x[lo:lo + chunk]
        d = norms[None, :] - 2.0 * part @ codebook.T
        index[lo:lo + chunk] = np.argmin(d, axis=1)
        dist[lo:lo + chunk] = (d[np.arange(len(part)), index[lo:lo + chunk]]
                               + np.einsum("nd,nd->n", part, part))
    return index, np.maximum(dist, 0.0)


def kmeans(x: np.ndarray, k: int, iters: int, seed: int = 0) -> np.ndarray:
    """Codebook (k, d) of ``x`` (N, d) by Lloyd's iterations from k random rows; an emptied
    cell takes the row farthest from its centre."""
    rng = np.random.default_rng(seed)
    x = x.astype(np.float32)
    codebook = x[rng.choice(len(x), k, replace=False)].copy()
    for _ in range(iters):
        index, dist = nearest(x, codebook)
        counts = np.bincount(index, minlength=k)
        sums = np.zeros_like(codebook, dtype=np.float64)
        np.add.at(sums, index, x)
        filled = counts > 0
        codebook[filled] = (sums[filled] / counts[filled, None]).astype(np.float32)
        empty = np.flatnonzero(~filled)
        if empty.size:
            codebook[empty] = x[np.argsort(dist)[::-1][:empty.size]]
    return codebook


def band_of_dims(degree: int, per_colour: bool) -> np.ndarray:
    """SH band (1..degree) of each dimension of a rest vector (coefficient-major, RGB)."""
    bands = np.concatenate([np.full(SH_REST_COUNTS[b] - SH_REST_COUNTS[b - 1], b)
                            for b in range(1, degree + 1)])
    return bands if per_colour else np.repeat(bands, 3)


def vq_row(rest: np.ndarray, degree: int, kind: str, k: int, steps: dict, iters: int,
           codebook_step: float, residual: float) -> tuple[np.ndarray, dict]:
    """(decoded rest (N, B, 3), cost record) of one VQ variant of the input bands ``rest``;
    ``residual``: the residual stage's step over the band's scalar step (0: none)."""
    n, coeffs = rest.shape[0], SH_REST_COUNTS[degree]
    bands = rest[:, :coeffs, :]
    per_colour = kind == "vq15"
    x = (bands.transpose(0, 2, 1).reshape(3 * n, coeffs) if per_colour
         else bands.reshape(n, coeffs * 3))
    band = band_of_dims(degree, per_colour)
    step = np.array([steps[f"rest{b}"] for b in band], np.float64)
    start = time.perf_counter()
    codebook = kmeans(x, k, iters)
    grid = np.rint(codebook / (codebook_step * step)).astype(np.int64)
    codebook = (grid * codebook_step * step).astype(np.float32)
    index, _ = nearest(x, codebook)
    cost = {"codebook_bits": sum(adaptive_bits(grid[:, band == b])
                                 for b in range(1, degree + 1))}
    if per_colour:
        colour_index = index.reshape(n, 3)
        cost["index_bits"] = sum(adaptive_bits(colour_index[:, c]) for c in range(3))
        cost["index_bits_order0"] = sum(order0_bits(colour_index[:, c]) for c in range(3))
    else:
        cost["index_bits"] = adaptive_bits(index)
        cost["index_bits_order0"] = order0_bits(index)
    decoded = codebook[index].astype(np.float64)
    cost["residual_bits"] = 0.0
    if residual:
        levels = np.rint((x - decoded) / (residual * step)).astype(np.int64)
        cost["residual_bits"] = sum(adaptive_bits(levels[:, c]) for c in range(x.shape[1]))
        cost["residual_zero_share"] = float(np.mean(levels == 0))
        decoded = decoded + levels * residual * step
    cost["vq_bits"] = cost["codebook_bits"] + cost["index_bits"] + cost["residual_bits"]
    cost["vq_seconds"] = time.perf_counter() - start
    cost["rms_error"] = float(np.sqrt(np.mean((decoded - x) ** 2)))
    out = np.zeros_like(rest)
    out[:, :coeffs, :] = (decoded.reshape(n, 3, coeffs).transpose(0, 2, 1) if per_colour
                          else decoded.reshape(n, coeffs, 3))
    return out, cost


def coded_vq_row(rest: np.ndarray, degree: int, k: int, steps: dict, iters: int,
                 codebook_step: float) -> tuple[np.ndarray, dict]:
    """(decoded rest (N, B, 3), cost record) of ``vq45_K{k}_coded``: the whole-vector codebook
    written with the codec's own coders, so its cost is bytes, not an estimate: each band's
    columns of the codebook as a float stream (:func:`write_float_stream`, step
    ``codebook_step`` times the band's scalar step), the indices, assigned to the nearest
    *decoded* codebook row, as a categorical stream with its table
    (:func:`encode_categorical`, K <= 255), plus 4 bytes for K and the bands (a chunk's
    header)."""
    from csgs_codec.attributes.float_stream import write_float_stream
    from csgs_codec.entropy.categorical import encode_categorical
    from csgs_codec.format.primitives import ByteWriter

    n, coeffs = rest.shape[0], SH_REST_COUNTS[degree]
    x = rest[:, :coeffs, :].reshape(n, coeffs * 3)
    band = band_of_dims(degree, False)
    start = time.perf_counter()
    codebook = kmeans(x, k, iters).astype(np.float64)
    out = ByteWriter()
    for b in range(1, degree + 1):
        cols = band == b
        codebook[:, cols] = write_float_stream(out, codebook[:, cols].astype(np.float32),
                                               codebook_step * steps[f"rest{b}"])
    index, _ = nearest(x, codebook.astype(np.float32))
    indices = encode_categorical(index, k)
    cost = {"codebook_bits": 8.0 * len(out), "index_bits": 8.0 * len(indices),
            "index_bits_order0": order0_bits(index), "residual_bits": 0.0}
    cost["vq_bits"] = cost["codebook_bits"] + cost["index_bits"] + 32.0
    cost["vq_seconds"] = time.perf_counter() - start
    decoded = codebook[index]
    cost["rms_error"] = float(np.sqrt(np.mean((decoded - x) ** 2)))
    result = np.zeros_like(rest)
    result[:, :coeffs, :] = decoded.reshape(n, coeffs, 3)
    return result, cost


def default_encode(scene, held: HeldOut, quality: int, rest_scale: float = 1.0
                   ) -> tuple[dict, object]:
    """(row, EncodeReport) of the default encode at ``quality`` (its SH-band step times
    ``rest_scale``), scored."""
    start = time.perf_counter()
    encoder = Encoder(quality=quality)
    if rest_scale != 1.0:
        encoder.preset = replace(PRESETS[quality], rest_step=PRESETS[quality].rest_step
                                 * rest_scale)
    result = encoder.encode_with_report(scene)
    variant = "scalar" if rest_scale == 1.0 else f"scalar_rest_x{rest_scale:g}"
    row = {"quality": quality, "variant": variant, "file_bytes": len(result.data),
           "sh_bytes": sum(result.stream_bytes.get(c, 0) for c in SH_CHUNKS),
           "encode_seconds": time.perf_counter() - start,
           "held_out_fg_psnr_db": held.psnr(result.reconstruction)}
    return row, result


def ratio(curve, nbytes: float, psnr: float) -> float | None:
    """``nbytes`` over the preset curve's bytes at ``psnr`` (None outside the curve)."""
    needed = size_at_psnr(curve, psnr)
    return None if np.isnan(needed) else nbytes / needed


def is_scalar(row: dict) -> bool:
    """A row of a real scalar encode, or its no-SH control."""
    return row["variant"].startswith("scalar") or row["variant"] == "no_sh_bands"


def envelope(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The (psnr, bytes) points no other point beats on both counts."""
    return [(p, b) for p, b in points
            if not any(q >= p and c <= b and (q, c) != (p, b) for q, c in points)]


def score(rows: list[dict], qualities: list[int]) -> None:
    """Add the ratios against the scalar points of the row's quality and against the
    envelope of every scalar point (docstring) to ``rows``."""
    best = envelope([(r["held_out_fg_psnr_db"], r["file_bytes"]) for r in rows
                     if is_scalar(r)])
    for quality in qualities:
        same = [r for r in rows if r["quality"] == quality]
        local = envelope([(r["held_out_fg_psnr_db"], r["file_bytes"]) for r in same
                          if is_scalar(r)])
        for r in same:
            r["ratio_vs_scalar_sh_curve"] = ratio(local, r["file_bytes"],
                                                  r["held_out_fg_psnr_db"])
            r["ratio_vs_scalar_envelope"] = ratio(best, r["file_bytes"],
                                                  r["held_out_fg_psnr_db"])


def rescore(path: str) -> None:
    """Recompute the derived ratios of a result file in place (after a scoring change)."""
    import json

    doc = json.loads(Path(path).read_text())
    score(doc["results"], doc["settings"]["qualities"])
    emit(doc, path)


def main() -> int:
    """Encode the preset curve, then each VQ variant at each quality; write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--qualities", type=int, nargs="+", default=[3, 5, 7])
    parser.add_argument("--curve", type=int, nargs="+", default=list(range(2, 10)))
    parser.add_argument("--kinds", nargs="+", default=["vq45", "vq15"])
    parser.add_argument("--ks", type=int, nargs="+", default=[64, 256, 1024, 4096])
    parser.add_argument("--residual-ks", type=int, nargs="*", default=[256, 1024])
    parser.add_argument("--residual-scales", type=float, nargs="*", default=[1.0, 2.0])
    parser.add_argument("--rest-scales", type=float, nargs="*", default=[0.5, 2.0, 4.0])
    parser.add_argument("--coded-ks", type=int, nargs="*", default=[],
                        help="K (<= 255) of whole-vector codebooks written with the codec's "
                             "own coders (vq45_K*_coded rows: real bytes)")
    parser.add_argument("--iters", type=int, default=8)
    parser.add_argument("--codebook-step", type=float, default=0.25)
    parser.add_argument("--subset", type=int, help="a fixed random subset (seed 0) of N")
    parser.add_argument("--size", default="400x300")
    parser.add_argument("--out")
    parser.add_argument("--rescore", action="store_true",
                        help="SCENE is a result file: recompute its ratios in place")
    args = parser.parse_args()
    if args.rescore:
        rescore(args.scene)
        return 0
    width, height = (int(v) for v in args.size.split("x"))
    scene = read_ply(args.scene)
    if args.subset and args.subset < len(scene):
        rng = np.random.default_rng(0)
        scene = scene.subset(np.sort(rng.choice(len(scene), args.subset, replace=False)))
    degree = scene.sh_degree_in_use()
    name = Path(args.scene).name
    start = time.perf_counter()
    held = HeldOut(scene, width, height)
    rows, results = [], {}
    for quality in sorted(set(args.curve) | set(args.qualities)):
        row, result = default_encode(scene, held, quality)
        rows.append({"scene": name, "gaussians": len(scene), **row})
        if quality in args.qualities:
            results[quality] = result
        print({k: v for k, v in rows[-1].items()}, file=sys.stderr, flush=True)
    curve = [(r["held_out_fg_psnr_db"], r["file_bytes"]) for r in rows]
    for r in rows:
        r["ratio_vs_presets"] = ratio(curve, r["file_bytes"], r["held_out_fg_psnr_db"])
        r["on_curve"] = r["quality"] in args.curve
    scalar = {r["quality"]: r for r in rows}
    for quality in args.qualities:
        result = results[quality]
        base = scalar[quality]
        settings = preset(quality)
        if result.allocation is not None:
            settings = result.allocation.apply(settings)
        steps = preset_steps(settings)
        rest = scene.sh_rest[result.order].astype(np.float64)
        for scale in args.rest_scales:
            row, _ = default_encode(scene, held, quality, scale)
            row["ratio_vs_presets"] = ratio(curve, row["file_bytes"],
                                            row["held_out_fg_psnr_db"])
            rows.append({"scene": name, "gaussians": len(scene), **row})
            print(rows[-1], file=sys.stderr, flush=True)
        bare = replace(result.reconstruction, sh_rest=np.zeros_like(rest, np.float32))
        nbytes = base["file_bytes"] - base["sh_bytes"]
        psnr = held.psnr(bare)
        rows.append({"scene": name, "gaussians": len(scene), "quality": quality,
                     "variant": "no_sh_bands", "file_bytes": nbytes, "vq_bytes": 0,
                     "scalar_sh_bytes": base["sh_bytes"], "held_out_fg_psnr_db": psnr,
                     "delta_db_vs_scalar": psnr - base["held_out_fg_psnr_db"],
                     "bytes_vs_scalar": nbytes / base["file_bytes"],
                     "ratio_vs_presets": ratio(curve, nbytes, psnr)})
        print(rows[-1], file=sys.stderr, flush=True)
        variants = [(kind, k, 0.0) for kind in args.kinds for k in args.ks]
        variants += [(kind, k, r) for kind in args.kinds for k in args.residual_ks
                     for r in args.residual_scales]
        variants += [("coded", k, 0.0) for k in args.coded_ks]
        for kind, k, residual in variants:
            vectors = (3 if kind == "vq15" else 1) * len(scene)
            if k > vectors // 2:
                continue
            if kind == "coded":
                decoded, cost = coded_vq_row(rest, degree, k, steps, args.iters,
                                             args.codebook_step)
            else:
                decoded, cost = vq_row(rest, degree, kind, k, steps, args.iters,
                                       args.codebook_step, residual)
            candidate = replace(result.reconstruction, sh_rest=decoded.astype(np.float32))
            nbytes = base["file_bytes"] - base["sh_bytes"] + cost["vq_bits"] / 8
            psnr = held.psnr(candidate)
            row = {"scene": name, "gaussians": len(scene), "quality": quality,
                   "variant": (f"vq45_K{k}_coded" if kind == "coded" else f"{kind}_K{k}"
                               + (f"_res{residual:g}" if residual else "")),
                   "file_bytes": nbytes, "scalar_sh_bytes": base["sh_bytes"],
                   "vq_bytes": cost["vq_bits"] / 8, **cost,
                   "band_steps": [steps[f"rest{b}"] for b in range(1, degree + 1)],
                   "held_out_fg_psnr_db": psnr,
                   "delta_db_vs_scalar": psnr - base["held_out_fg_psnr_db"],
                   "bytes_vs_scalar": nbytes / base["file_bytes"],
                   "ratio_vs_presets": ratio(curve, nbytes, psnr)}
            rows.append(row)
            print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()
                   if k != "band_steps"}, file=sys.stderr, flush=True)
    score(rows, args.qualities)
    emit(document("sh_vector_codebook", rows, settings=vars(args), sh_degree=degree,
                  held_out_views=f"16 @20deg + 12 @45deg, {args.size}",
                  seconds=time.perf_counter() - start), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
