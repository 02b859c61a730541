"""File sizes of the default encoder on every shared scene at a set of presets (issue 33's
check that a format change keeps files within 0.1% of their size, or smaller).

    .venv/bin/python benchmarks/preset_sizes.py [--qualities 1 3 5 7 9 11]
        [--compare BEFORE.json] [--out FILE]

Run it on two checkouts (``PYTHONPATH=/path/to/checkout``, the same scenes and machine) and
pass the first run's output as ``--compare`` to the second: each row then carries the
earlier size and the ratio. Sizes depend on the code only (the encoder is deterministic).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
SCENES = [SHARED / "scenes" / f"{name}.ply" for name in
          ("donut", "biker", "guitar", "plant", "playbot")] + [
    SHARED / "real_sh3" / "fruit_drops.ply", SHARED / "real_sh3" / "leica_sofort_top8192.ply"]


def main() -> int:
    """Encode every present scene at every quality and write the sizes."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--qualities", type=int, nargs="+", default=[1, 3, 5, 7, 9, 11])
    parser.add_argument("--compare", help="an earlier run's output to compare with")
    parser.add_argument("--out")
    args = parser.parse_args()
    import csgs_codec
    from csgs_codec import Encoder, read_ply

    earlier = {}
    if args.compare:
        earlier = {(r["scene"], r["quality"]): r["bytes"]
                   for r in json.loads(Path(args.compare).read_text())["results"]}
    rows = []
    for path in (p for p in SCENES if p.exists()):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = read_ply(path)
        for quality in args.qualities:
            start = time.perf_counter()
            size = len(Encoder(quality=quality).encode(scene))
            row = {"scene": path.name, "quality": quality, "bytes": size,
                   "encode_s": time.perf_counter() - start}
            if (path.name, quality) in earlier:
                row["bytes_before"] = earlier[path.name, quality]
                row["ratio"] = size / row["bytes_before"]
            rows.append(row)
            print(row, file=sys.stderr, flush=True)
    emit(document("preset_sizes", rows, settings=vars(args),
                  package=str(Path(csgs_codec.__file__).parent)), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
