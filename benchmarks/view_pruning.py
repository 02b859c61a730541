"""View pruning against the plain encode, scored only on views not used to allocate.

For each scene and quality: encode without and with ``view_pruning`` (the default sphere of
views, or ``--budget`` values), decode, check the round trip, and score foreground PSNR on
held-out views that the encoder never rendered: 16 orbit views at 20 degrees and 12 at 45
degrees elevation at ``--size`` (the issue's protocol). Rows give bits per Gaussian of the
input, the share left out, held-out PSNR, encode time, and ``ratio_at_equal_psnr``: the
pruned file's size over the size the plain encode needs for the same held-out PSNR
(interpolated log-linearly on the plain encodes at qualities 1..9 of the same run).

    .venv/bin/python benchmarks/view_pruning.py --scenes donut plant --out vp.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import FULL_PRECISION, SCENES, document, emit, held_out_views  # noqa: E402

from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402
from csgs_codec.metrics.comparison import render_references, score_view  # noqa: E402


def mean_fg_psnr(refs, scene, cameras) -> float:
    """Mean foreground PSNR (dB) of ``scene`` over ``cameras``."""
    values = [score_view(r, scene, c, backend="numba").foreground_psnr
              for r, c in zip(refs, cameras)]
    return float(np.nanmean(values))


def run_case(name, original, refs, cameras, quality, budget) -> dict:
    """One encode (plain when ``budget`` is None), decoded, checked and scored."""
    encoder = Encoder(quality=quality, hyperprior=False, view_pruning=budget is not None,
                      view_budget=0.0 if budget is None else budget)
    start = time.perf_counter()
    result = encoder.encode_with_report(original)
    encode_s = time.perf_counter() - start
    decoded = Decoder().decode(result.data)
    if not decoded.equals(result.reconstruction):
        raise SystemExit(f"{name} q{quality}: decode differs from the encoder's reconstruction")
    return {"scene": f"{name}.ply", "full_precision": name in FULL_PRECISION,
            "quality": quality, "view_budget": budget, "bytes": len(result.data),
            "bits_per_input_gaussian": 8 * len(result.data) / len(original),
            "left_out_share": result.view_pruned / len(original),
            "held_out_fg_psnr_db": mean_fg_psnr(refs, decoded, cameras),
            "encode_s": encode_s}


def size_at_psnr(curve: list[dict], psnr: float) -> float:
    """Bytes the plain encodes need for ``psnr`` (log-size linear in PSNR; nan outside)."""
    points = sorted((r["held_out_fg_psnr_db"], r["bytes"]) for r in curve)
    xs = [p for p, _ in points]
    if not xs[0] <= psnr <= xs[-1]:
        return float("nan")
    return float(np.exp(np.interp(psnr, xs, [np.log(b) for _, b in points])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["donut", "plant"])
    parser.add_argument("--qualities", nargs="+", type=int, default=[2, 5, 8])
    parser.add_argument("--budgets", nargs="+", type=float, default=[0.1])
    parser.add_argument("--size", default="800x600", help="held-out view size WxH")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    rows = []
    for name in args.scenes:
        original = read_ply(SCENES / f"{name}.ply")
        cameras = held_out_views(original, width, height)
        refs = render_references(original, cameras, backend="numba")
        plain = [run_case(name, original, refs, cameras, q, None) for q in range(1, 10)]
        rows += [r for r in plain if r["quality"] in args.qualities]
        for quality in args.qualities:
            for budget in args.budgets:
                row = run_case(name, original, refs, cameras, quality, budget)
                row["ratio_at_equal_psnr"] = row["bytes"] / size_at_psnr(
                    plain, row["held_out_fg_psnr_db"])
                rows.append(row)
                print(f"{name} q{quality} budget {budget}: {row}", file=sys.stderr)
    emit(document("view_pruning", rows, held_out_views=f"16 @20deg + 12 @45deg, {args.size}",
                  allocation="default sphere: 16 directions x 3 distances, 800x600"), args.out)


if __name__ == "__main__":
    main()
