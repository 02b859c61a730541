"""Geometry coding benchmark: bits per point and decode speed against Draco, in one run.

Every shared scene's positions are quantized to 16 bits per axis over their bounding box.
csgs codes the integer grid with :func:`encode_positions`; Draco (PyPI DracoPy) codes the same
grid as a point cloud with ``quantization_bits=16``, the best compression level, origin 0 and
range 65535, so its quantization maps every grid value to itself. Both round trips are checked
before anything is timed: csgs as a multiset (duplicates counted, canonical order), Draco as a
set, because Draco's point-cloud coder drops repeated points. So the comparison favours Draco:
csgs also pays for the repeat counts (``csgs_distinct_bytes`` gives its size on the distinct
set alone). Neither keeps the input order. Sizes are whole payloads (Draco's header included)
and bits per point divide by the input point count N for both. Times are the best of
``--repeat`` runs (wall and process CPU time). A composite of all five scenes (each at 15 bits
in its own octant of the 16-bit grid, 651k points) gives one larger set for decode time per
10^6 points.

    .venv/bin/python benchmarks/geometry.py [--repeat 5] [--out geometry.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from csgs_codec.entropy.geometry import (  # noqa: E402
    canonical_order,
    decode_positions,
    encode_positions,
)
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402

SCENES = REPO.parent / "shared" / "data" / "scenes"
BITS = 16


def quantize_to_grid(positions: np.ndarray, bits: int) -> np.ndarray:
    """(N, 3) float positions -> (N, 3) int64 on a 2^bits grid over their bounding box."""
    p = positions.astype(np.float64)
    low, high = p.min(axis=0), p.max(axis=0)
    extent = np.where(high > low, high - low, 1.0)
    return np.round((p - low) / extent * ((1 << bits) - 1)).astype(np.int64)


def best_time(fn, repeat: int) -> tuple[float, float]:
    """(fastest wall time, fastest process CPU time) over ``repeat`` calls, in seconds."""
    wall, cpu = float("inf"), float("inf")
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    return wall, cpu


def same_set(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two (N, 3) integer point arrays hold the same distinct points."""
    return bool(np.array_equal(np.unique(a, axis=0), np.unique(b, axis=0)))


COMPOSITE = "composite_8_octants"


def point_sets() -> list[tuple[str, np.ndarray]]:
    """(name, (N, 3) int64 grid positions): every scene, then all scenes in one 16-bit grid.

    The composite quantizes each scene to 15 bits and puts it in its own octant of the
    16-bit grid (octants 0..4), giving one larger point set for decode speed per point.
    """
    sets, parts = [], []
    for index, path in enumerate(sorted(SCENES.glob("*.ply"))):
        positions = read_ply(path).positions
        sets.append((path.stem, quantize_to_grid(positions, BITS)))
        offset = np.array([(index >> axis) & 1 for axis in range(3)]) << (BITS - 1)
        parts.append(quantize_to_grid(positions, BITS - 1) + offset)
    sets.append((COMPOSITE, np.concatenate(parts)))
    return sets


def bench_csgs(q: np.ndarray, repeat: int) -> dict:
    payload = encode_positions(q, BITS)
    decoded = decode_positions(payload)
    if not np.array_equal(decoded, q[canonical_order(q, BITS)]):
        raise SystemExit("csgs geometry round trip failed")
    return timed(payload, q.shape[0], lambda: encode_positions(q, BITS),
                 lambda: decode_positions(payload), repeat)


def timed(payload: bytes, n: int, encode, decode, repeat: int) -> dict:
    """Size and best-of-``repeat`` encode/decode times of one coder on one point set."""
    encode_s, _ = best_time(encode, repeat)
    decode_s, decode_cpu_s = best_time(decode, repeat)
    return {"bytes": len(payload), "bits_per_point": 8 * len(payload) / n,
            "encode_s": encode_s, "decode_s": decode_s, "decode_cpu_s": decode_cpu_s,
            "decode_s_per_million_points": decode_s * 1e6 / n,
            "decode_cpu_s_per_million_points": decode_cpu_s * 1e6 / n}


def bench_draco(q: np.ndarray, repeat: int) -> dict:
    import DracoPy

    points = q.astype(np.float32)
    top = float((1 << BITS) - 1)

    def encode():
        return DracoPy.encode(points, quantization_bits=BITS, compression_level=10,
                              quantization_range=top, quantization_origin=[0.0, 0.0, 0.0])

    payload = encode()
    decoded = np.rint(np.asarray(DracoPy.decode(payload).points, np.float64)).astype(np.int64)
    if not same_set(decoded, q):
        raise SystemExit("Draco round trip is not lossless on the 16-bit grid")
    return timed(payload, q.shape[0], encode, lambda: DracoPy.decode(payload), repeat)


def main() -> int:
    """Run the benchmark on every shared scene and print (and optionally write) the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    results = []
    for name, q in point_sets():
        csgs = bench_csgs(q, args.repeat)
        draco = bench_draco(q, args.repeat)
        results.append({
            "scene": name, "points": int(q.shape[0]),
            "distinct_points": int(np.unique(q, axis=0).shape[0]), "bits_per_axis": BITS,
            "csgs": csgs, "draco": draco,
            "csgs_distinct_bytes": len(encode_positions(np.unique(q, axis=0), BITS)),
            "bits_ratio_csgs_over_draco": csgs["bits_per_point"] / draco["bits_per_point"],
            "decode_time_ratio_csgs_over_draco": csgs["decode_s"] / draco["decode_s"],
        })
    scenes = [r for r in results if r["scene"] != COMPOSITE]
    total_points = sum(r["points"] for r in scenes)
    summary = {
        side: {
            "bits_per_point": 8 * sum(r[side]["bytes"] for r in scenes) / total_points,
            "decode_s_per_million_points": 1e6 * sum(r[side]["decode_s"] for r in scenes)
            / total_points,
        }
        for side in ("csgs", "draco")
    }
    summary["note"] = "sums over the five scenes (composite excluded)"
    report = {
        "schema": "csgs-bench/1",
        "benchmark": "geometry",
        "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                    "python": platform.python_version()},
        "settings": {"bits_per_axis": BITS, "repeat": args.repeat,
                     "draco": "DracoPy point cloud, quantization_bits=16, compression_level=10, "
                              "origin 0, range 65535 (keeps distinct points only)"},
        "results": results,
        "summary": summary,
    }
    text = json.dumps(report, indent=2)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
