"""Bytes and held-out foreground PSNR of default encodes at a few qualities, for comparing two
versions of the encoder (run it once per version, e.g. one from a git worktree with
PYTHONPATH pointing there).

    .venv/bin/python benchmarks/encode_points.py SCENE.ply [SCENE.ply ...]
        [--qualities 3 5 7] [--size 400x300] [--label NAME] [--out FILE]

Each scene is rendered on the held-out views (16 orbit views at 20 degrees + 12 at 45, at
``--size``, none used by the encoder), then encoded with ``Encoder(quality=q)`` and decoded;
rows give the bytes, the mean foreground PSNR against the original's renders, whether the
encoder sorted the axes (``EncodeReport.sorted_axes``, null where the version has no such
field) and ``--label`` (say, the commit).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402
from derived_steps import HeldOut  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--qualities", nargs="+", type=int, default=[3, 5, 7])
    parser.add_argument("--size", default="400x300")
    parser.add_argument("--label", default="")
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    from csgs_codec.codec.decoder import Decoder
    from csgs_codec.codec.encoder import Encoder
    from csgs_codec.codec.files import read_scene

    width, height = (int(v) for v in args.size.split("x"))
    rows = []
    for path in args.scenes:
        scene = read_scene(path)
        held = HeldOut(scene, width, height)
        for quality in args.qualities:
            report = Encoder(quality=quality).encode_with_report(scene)
            rows.append({"scene": Path(path).stem, "label": args.label, "quality": quality,
                         "bytes": len(report.data),
                         "held_out_fg_psnr_db": held.psnr(Decoder().decode(report.data)),
                         "sorted_axes": getattr(report, "sorted_axes", None)})
            print(rows[-1], file=sys.stderr, flush=True)
    emit(document("encode_points", rows, held_out_views=f"16 @20deg + 12 @45deg, {args.size}"),
         args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
