"""Initial points from pycolmap at known poses: how many, how close to the real surface, how long.

    python benchmarks/sfm_points.py [--scene ../shared/data/scenes/plant.ply] [--views 48]
        [--size 800x600] [--out FILE]

The scene is rendered (own rasterizer) from ``--views`` orbit cameras at ``--size``: the
training set of issue #31's real-scene protocol. csgs_codec.train.sfm_points triangulates
points from those images at those cameras (a fresh cache folder, so nothing is reused).
Reported: points, seconds (render, triangulation), and each point's distance to the nearest
Gaussian centre as a fraction of the scene's robust extent (1st-99th percentile box), median
and 90th percentile. The JSON uses schema csgs-bench/1.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_common import REPO, document, emit  # noqa: E402

DEFAULT_SCENE = REPO.parent / "shared" / "data" / "scenes" / "plant.ply"


def main() -> int:
    """Parse arguments, run, print or write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(DEFAULT_SCENE))
    parser.add_argument("--views", type=int, default=48)
    parser.add_argument("--size", default="800x600")
    parser.add_argument("--notes", default="")
    parser.add_argument("--out")
    args = parser.parse_args()
    import numpy as np

    from csgs_codec.interchange.ply_io import read_ply
    from csgs_codec.metrics.attribute_errors import nearest_neighbours
    from csgs_codec.render.rasterizer import render
    from csgs_codec.scene.orbit import orbit_cameras
    from csgs_codec.train.sfm_points import triangulate_views
    from csgs_codec.train.views import TrainingView

    width, height = (int(v) for v in args.size.split("x"))
    scene = read_ply(args.scene)
    began = time.perf_counter()
    views = [TrainingView(np.clip(render(scene, c, backend="numba").image, 0, 1)
                          .astype(np.float32), c, name=c.name)
             for c in orbit_cameras(scene, args.views, width=width, height=height)]
    render_s = time.perf_counter() - began
    with tempfile.TemporaryDirectory() as cache:
        began = time.perf_counter()
        found = triangulate_views(views, cache=Path(cache))
        triangulate_s = time.perf_counter() - began
    positions = scene.positions.astype(np.float64)
    low, high = np.percentile(positions, 1, axis=0), np.percentile(positions, 99, axis=0)
    extent = float(np.max(high - low))
    _, distance = nearest_neighbours(found.points, positions)
    row = {"scene": Path(args.scene).name, "gaussians": len(scene), "views": args.views,
           "size": args.size, "points": len(found.points),
           "seconds": {"render": round(render_s, 3), "triangulate": round(triangulate_s, 3)},
           "distance_over_extent_median": float(np.median(distance) / extent),
           "distance_over_extent_p90": float(np.percentile(distance, 90) / extent)}
    emit(document("sfm_points", [row], notes=args.notes), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
