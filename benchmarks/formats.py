"""Interchange formats: bytes, bits per Gaussian and csgs's write and read times per format.

For each scene, each writer of ``csgs decode -o`` (.ply, .splat, .spz v4, .glb) is timed
writing the scene to bytes and the matching reader reading them back (best of ``--repeat``
runs, one thread, wall seconds), after checking the round trip (positions within the
format's precision, Gaussian count kept).

    .venv/bin/python benchmarks/formats.py --out benchmarks/results/formats_2026-11-24.json
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_common import FULL_PRECISION, SCENES, best_of, document, emit  # noqa: E402
from csgs_codec.codec.files import read_scene_with_report  # noqa: E402
from csgs_codec.errors import DataLossWarning  # noqa: E402
from csgs_codec.interchange.writers import scene_bytes  # noqa: E402

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "donut.ply"
#: suffix -> largest position error the format allows for a scene within +-2048 units
POSITION_TOLERANCE = {".ply": 0.0, ".splat": 0.0, ".spz": 2.0 ** -13 + 1e-6, ".glb": 0.0}


def measure(path: Path, repeat: int) -> list[dict]:
    """One row per output format for the scene at ``path``."""
    scene, _ = read_scene_with_report(path)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for suffix, tolerance in POSITION_TOLERANCE.items():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DataLossWarning)
                write_s, data = best_of(repeat, lambda s=suffix: scene_bytes(scene, s))
            out = Path(folder) / f"scene{suffix}"
            out.write_bytes(data)
            read_s, (back, source) = best_of(repeat, lambda o=out: read_scene_with_report(o))
            assert len(back) == len(scene)
            if suffix in (".ply", ".glb", ".splat"):  # same order as written
                error = float(np.abs(back.positions - scene.positions).max())
                assert error <= tolerance, (suffix, error)
            rows.append({"scene": path.name, "full_precision": path.stem in FULL_PRECISION,
                         "gaussians": len(scene), "sh_degree": scene.sh_degree_stored,
                         "format": source.title(), "suffix": suffix, "bytes": len(data),
                         "bits_per_gaussian": 8 * len(data) / len(scene),
                         "write_s": write_s, "read_s": read_s})
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=None)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--scenes", nargs="*", default=["donut", "playbot"],
                        help="names under ../shared/data/scenes (donut falls back to the "
                             "bundled sample)")
    args = parser.parse_args()
    results = []
    for name in args.scenes:
        path = SCENES / f"{name}.ply"
        if not path.is_file():
            if name != "donut":
                continue
            path = SAMPLE
        results += measure(path, args.repeat)
    emit(document("formats", results), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
