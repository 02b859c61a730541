"""Are the SH bands over- or under-coded? Real encodes with the SH-rest step scaled.

    .venv/bin/python benchmarks/sh_step_scale.py SCENE.ply [--scales 2] [--qualities 3 5 7]
        [--curve-qualities 2 3 4 5 6 7 8] [--size 400x300] [--out FILE]

The default encoder (hyperprior, rotation steps by footprint) codes the scene at every
``--curve-qualities`` preset (the reference curve) and, at ``--qualities``, with the preset's
SH-rest step (bands 1-3) multiplied by each ``--scales`` value, every other step as the
preset has it. Each row gives the bytes, the SH-band bytes and the mean foreground PSNR over
the held-out views (16 orbit views at 20 degrees + 12 at 45, at ``--size``, none used by the
encoder); ``ratio_vs_presets`` is the row's bytes over what the reference curve needs for its
PSNR (log-size linear in PSNR; null outside the curve): below 1, the scaled SH step codes the
scene smaller at equal quality.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402
from derived_steps import HeldOut, size_at_psnr  # noqa: E402

from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import PRESETS  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402


def encode_row(scene, held: HeldOut, quality: int, scale: float) -> dict:
    """One encode at ``quality`` with the SH-rest step times ``scale``, scored."""
    encoder = Encoder(quality=quality)
    encoder.preset = replace(PRESETS[quality], rest_step=PRESETS[quality].rest_step * scale)
    result = encoder.encode_with_report(scene)
    sh_bytes = sum(v for k, v in result.stream_bytes.items() if k.startswith("SHB"))
    return {"quality": quality, "rest_scale": scale, "bytes": len(result.data),
            "sh_band_bytes": sh_bytes, "held_out_fg_psnr_db": held.psnr(result.reconstruction)}


def main() -> int:
    """Parse arguments, encode, score, write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--scales", type=float, nargs="+", default=[2.0])
    parser.add_argument("--qualities", type=int, nargs="+", default=[3, 5, 7])
    parser.add_argument("--curve-qualities", type=int, nargs="+",
                        default=[2, 3, 4, 5, 6, 7, 8])
    parser.add_argument("--size", default="400x300")
    parser.add_argument("--out")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    scene = read_ply(args.scene)
    held = HeldOut(scene, width, height)
    name = Path(args.scene).name
    rows = []
    for quality in args.curve_qualities:
        rows.append({"scene": name, **encode_row(scene, held, quality, 1.0)})
        print(rows[-1], file=sys.stderr)
    curve = [(r["held_out_fg_psnr_db"], r["bytes"]) for r in rows]
    for scale in args.scales:
        for quality in args.qualities:
            row = {"scene": name, **encode_row(scene, held, quality, scale)}
            row["ratio_vs_presets"] = row["bytes"] / size_at_psnr(curve, row["held_out_fg_psnr_db"])
            rows.append(row)
            print(row, file=sys.stderr)
    emit(document("sh_step_scale", rows, settings=vars(args),
                  held_out_views=f"16 @20deg + 12 @45deg, {args.size}"), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
