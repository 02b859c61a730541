"""Default-encode time of real captures, and the share the step allocation takes.

For each scene and quality: the wall time of ``Encoder(quality=Q).encode`` (best of
``--repeat`` runs, after one warm-up encode that compiles the numba kernels), the time of
the step allocation alone (``allocate_steps`` with the encoder's inputs; it renders the
probe views of every candidate, and on SH-3 captures takes most of an encode), its number
of probe trials and the offsets it chose, and the file's size and SHA-256 (two codecs that
write the same bytes made the same decisions).

    .venv/bin/python benchmarks/encode_time.py [--scenes yashica_t4_top8192 fruit_drops]
        [--qualities 2 5 8] [--repeat 2] [--code LABEL] [--out FILE]

Scenes are looked up in benchmarks/data, ../shared/data/real_sh3 and ../shared/data/scenes
(absent ones are skipped, saying so). Like benchmarks/speed.py, it measures whichever
csgs_codec Python imports, so PYTHONPATH=DIR measures a frozen tree (``git archive``) while
the working copy changes; ``codec_path`` says which.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import REPO, best_of, document, emit  # noqa: E402

import csgs_codec  # noqa: E402
from csgs_codec import read_scene  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import preset  # noqa: E402
from csgs_codec.decisions.step_allocation import allocate_steps  # noqa: E402

DEFAULT_SCENES = ("yashica_t4_top8192", "fruit_drops", "leica_sofort_top8192")
FOLDERS = (REPO / "benchmarks" / "data", REPO.parent / "shared" / "data" / "real_sh3",
           REPO.parent / "shared" / "data" / "scenes")


def find_scene(name: str) -> Path | None:
    """The PLY of ``name`` in the first of :data:`FOLDERS` that has it, or None."""
    for folder in FOLDERS:
        path = folder / f"{name}.ply"
        if path.is_file():
            return path
    return None


def measure(path: Path, quality: int, repeat: int, keep: int | None = None) -> dict:
    """One row: encode and allocation times of the scene at ``path`` at ``quality`` (its
    first ``keep`` Gaussians when given)."""
    import warnings

    import numpy as np

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = read_scene(path)
    if keep is not None:
        scene = scene.subset(np.arange(min(keep, len(scene))))
    encoder = Encoder(quality=quality)
    encode_s, data = best_of(repeat, lambda: encoder.encode(scene))
    allocation_s, allocation = best_of(repeat, lambda: allocate_steps(scene, preset(quality)))
    return {"scene": path.stem, "gaussians": len(scene), "sh_degree": scene.sh_degree_in_use(),
            "quality": quality, "encode_s": encode_s, "allocation_s": allocation_s,
            "allocation_trials": allocation.trials, "allocation_offsets": allocation.offsets,
            "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def main(argv: list[str] | None = None) -> int:
    """Measure every scene and quality; print or write the JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES))
    parser.add_argument("--qualities", nargs="+", type=int, default=[5])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--code", default="", help="a label for the codec measured")
    parser.add_argument("--out")
    args = parser.parse_args(argv)

    warm = find_scene(args.scenes[0]) or REPO / "samples" / "donut.ply"
    measure(warm, args.qualities[0], 1, keep=2048)  # compiles the numba kernels, loads torch
    rows = []
    for name in args.scenes:
        path = find_scene(name)
        if path is None:
            print(f"skipped {name}: not found in {', '.join(map(str, FOLDERS))}",
                  file=sys.stderr)
            continue
        for quality in args.qualities:
            row = measure(path, quality, args.repeat)
            row["code"] = args.code
            rows.append(row)
            print(f"{name} q{quality}: encode {row['encode_s']:.2f} s, allocation "
                  f"{row['allocation_s']:.2f} s ({row['allocation_trials']} trials)",
                  file=sys.stderr)
    emit(document("encode_time", rows, codec_path=str(Path(csgs_codec.__file__).parent),
                  repeat=args.repeat), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
