"""``--refine N`` measured (issue 17 item 5): held-out dB and bytes of real files per CPU-minute.

For each scene and quality: the plain encode and ``Encoder(refine=N)`` for each N, both
without the color hyperprior (it changes the rate only, and its fit would blur the time).
Every row is a real file: ``bytes`` its length, ``held_out_fg_psnr_db`` the foreground PSNR
of its decode on views the refinement never used (16 orbit views at 20 degrees + 12 at 45
degrees, 800x600; refinement uses the default sphere of views at 400 pixels wide),
``cpu_s`` the encode's CPU time. ``ratio_vs_presets`` divides the bytes by what the plain
presets 1-9 need for the same held-out PSNR (log-size interpolated; nan outside their range),
so a refined file below 1 is smaller than any plain encode of its quality. ``--stacked``
adds view pruning and footprint rotation steps (scored steps) to each refined encode; the rest
use one rotation step (``rotation_steps="uniform"``), as when the results were first taken.

    .venv/bin/python benchmarks/refine.py --scenes donut plant --qualities 2 5 \\
        --steps 20 60 --out benchmarks/results/refine_DATE.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import FULL_PRECISION, SCENES, document, emit  # noqa: E402
from derived_steps import HeldOut, size_at_psnr  # noqa: E402

from csgs_codec.codec.decoder import Decoder  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402


def measure(scene, held: HeldOut, quality: int, steps: int, stacked: bool = False) -> dict:
    """One encode's bytes, held-out PSNR of its decode and CPU seconds; ``stacked`` adds
    view pruning and derived rotation steps to the refinement."""
    start = time.process_time()
    data = Encoder(quality=quality, hyperprior=False, refine=steps, view_pruning=stacked,
                   rotation_steps="footprint" if stacked else "uniform").encode(scene)
    cpu = time.process_time() - start
    return {"quality": quality, "refine_steps": steps, "stacked": stacked,
            "bytes": len(data), "held_out_fg_psnr_db": held.psnr(Decoder().decode(data)),
            "cpu_s": cpu}


def run_scene(name: str, qualities: list[int], step_counts: list[int],
              stacked: bool = False) -> list[dict]:
    """Rows of one scene: the plain presets 1..9, then each quality refined (with view
    pruning and derived steps too when ``stacked``)."""
    scene = read_ply(SCENES / f"{name}.ply")
    held = HeldOut(scene)
    base = {"scene": f"{name}.ply", "gaussians": len(scene),
            "full_precision": name in FULL_PRECISION}
    presets = [{**base, **measure(scene, held, q, 0)} for q in range(1, 10)]
    curve = [(r["held_out_fg_psnr_db"], r["bytes"]) for r in presets]
    rows = list(presets)
    for quality in qualities:
        plain = presets[quality - 1]
        for steps in step_counts:
            row = {**base, **measure(scene, held, quality, steps, stacked)}
            extra_cpu = row["cpu_s"] - plain["cpu_s"]
            row.update({
                "delta_db": row["held_out_fg_psnr_db"] - plain["held_out_fg_psnr_db"],
                "bytes_vs_plain": row["bytes"] / plain["bytes"],
                "ratio_vs_presets": row["bytes"] / size_at_psnr(curve,
                                                                row["held_out_fg_psnr_db"]),
                "db_per_cpu_minute": (row["held_out_fg_psnr_db"]
                                      - plain["held_out_fg_psnr_db"]) / (extra_cpu / 60)})
            print(row, file=sys.stderr)
            rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["donut"])
    parser.add_argument("--qualities", nargs="+", type=int, default=[2, 5])
    parser.add_argument("--steps", nargs="+", type=int, default=[20, 60])
    parser.add_argument("--stacked", action="store_true",
                        help="refine on top of view pruning and derived rotation steps "
                             "(the three opt-in distortion-side levers together)")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    rows = []
    for name in args.scenes:
        rows += run_scene(name, args.qualities, sorted(args.steps), args.stacked)
    emit(document("refine", rows, refinement_views="default sphere, 400 px wide",
                  held_out_views="16 @20deg + 12 @45deg, 800x600",
                  encoder="hyperprior off"), args.out)


if __name__ == "__main__":
    main()
