"""Anchor-scene coding benchmark: bits per anchor per attribute with and without CARM, the
semantic layer's share of the file, and decode times (color only, both layers).

    .venv/bin/python benchmarks/anchors.py [--rate-anchors 10000] [--time-anchors 100000]
                                           [--quality 5] [--repeat 3] [--out FILE]

Scenes come from ``synthetic_anchor_scene`` (5 labelled objects, F = 50 with 5
group-correlated channel groups, K = 10, 20% of offsets masked, S = 6, with MLPs). Every
encode is checked (decode == encoder reconstruction, bit for bit) before anything is timed.
Decode times are the best of ``--repeat`` runs, wall and process CPU time (on a shared
machine CPU time is the figure less distorted by other load); the target is <= 2 s for the
color layer of 100k anchors on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import document, emit  # noqa: E402

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.format import read_layers
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene

ATTRIBUTE_CHUNKS = {"features": "AFEA", "offsets": "AOFF", "scaling": "ASCL",
                    "masks": "AMSK", "positions": "GEOM", "hyperprior": "AHYP",
                    "carm": "ACRM", "mlps": "AMLP", "semantic": "ASEM",
                    "semantic_hyperprior": "SHYP", "labels": "SEML|SEMR"}  # "|": either


def checked_encode(scene, **kwargs):
    """Encode and verify the full decode equals the encoder's reconstruction."""
    result = AnchorEncoder(**kwargs).encode_with_report(scene)
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    if not decoded.equals(result.reconstruction):
        raise SystemExit("round trip failed: decode differs from the encoder reconstruction")
    return result


def rate_row(scene, quality: int, carm_groups: int) -> dict:
    """Bits per anchor per attribute, layer bytes and the semantic share."""
    result = checked_encode(scene, quality=quality, carm_groups=carm_groups)
    m = len(scene)
    container = read_layers(result.data, layers="color,semantic")
    layer_bytes = {}
    for entry in container.toc:
        layer_bytes[entry.layer.label] = layer_bytes.get(entry.layer.label, 0) + entry.frame_size
    semantic = layer_bytes.get("semantic", 0)
    return {
        "anchors": m, "quality": quality, "carm_groups": carm_groups,
        "file_bytes": len(result.data),
        "bits_per_anchor": {name: 8 * sum(result.chunk_bytes.get(c, 0)
                                          for c in codes.split("|")) / m
                            for name, codes in ATTRIBUTE_CHUNKS.items()},
        "bits_per_anchor_total": 8 * len(result.data) / m,
        "layer_bytes": layer_bytes,
        "semantic_share_percent": 100.0 * semantic / len(result.data),
        "encode_seconds": result.seconds, "fit_seconds": result.fit_seconds,
    }


def best(fn, repeat: int) -> tuple[float, float]:
    """(best wall seconds, best process CPU seconds) of ``repeat`` calls."""
    walls, cpus = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return min(walls), min(cpus)


def main() -> int:
    """Run the benchmark and print or write the JSON document."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rate-anchors", type=int, default=10_000)
    parser.add_argument("--time-anchors", type=int, default=100_000)
    parser.add_argument("--quality", type=int, default=5)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out")
    args = parser.parse_args()

    results = []
    scene = synthetic_anchor_scene(5, args.rate_anchors // 5)
    for groups in (1, 5):
        results.append({"kind": "rate", **rate_row(scene, args.quality, groups)})
    without, with_carm = results[0]["bits_per_anchor"], results[1]["bits_per_anchor"]
    results.append({"kind": "carm_gain", "anchors": len(scene),
                    "feature_bits_without": without["features"],
                    "feature_bits_with": with_carm["features"],
                    "feature_bits_saved_percent":
                        100.0 * (1 - with_carm["features"] / without["features"]),
                    "carm_network_bits": with_carm["carm"],
                    "net_bits_saved": without["features"] - with_carm["features"]
                    - with_carm["carm"]})

    big = synthetic_anchor_scene(5, args.time_anchors // 5)
    encoded = checked_encode(big, quality=args.quality)
    for layers in ("color", "color,semantic"):
        wall, cpu = best(lambda layers=layers: AnchorDecoder().decode(encoded.data, layers),
                         args.repeat)
        results.append({"kind": "decode_time", "anchors": len(big), "layers": layers,
                        "wall_seconds": wall, "cpu_seconds": cpu,
                        "threads": os.environ.get("OMP_NUM_THREADS", "default")})
    results.append({"kind": "encode_time", "anchors": len(big),
                    "wall_seconds": encoded.seconds, "fit_seconds": encoded.fit_seconds,
                    "file_bytes": len(encoded.data)})
    emit(document("anchors", results, quality=args.quality), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
