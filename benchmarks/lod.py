"""Levels of detail (issue #53): the cost of a file with levels against a single-level file,
how few bytes its coarsest level needs, and how each level looks against the full scene.

    .venv/bin/python benchmarks/lod.py [--scene PLY] [--copies 9] [--levels 3 4]
        [--tile-size 65536] [--views 3] [--widths 1600 800 400 200] [--keep N]
        [--quiet] [--out FILE]

The scene is ``--copies`` copies of ``--scene`` (by default the shared playbot capture,
248,155 Gaussians, SH 2, CC-BY-4.0) laid on a square grid across the two axes that are not
its up axis, a quarter of a copy's width apart (9 copies: 2,233,395 Gaussians), written to a
temporary PLY and read back. It is encoded four ways at the default quality, each timed once:
``Encoder()`` (the default: tiles of 1,000,000 above 2,000,000 Gaussians), the leaves of the
levels files without levels (``Encoder(tile_size=T)``), and ``Encoder(levels=L)`` for every
``--levels`` L (leaves of at most T = ``--tile-size``). Rows:

- ``encode``: seconds, bytes, bits per Gaussian (of the scene's own Gaussians), tiles, and
  the ratio of each file to the single-level one and to the same tiles without levels;
- ``level`` (every level of every levels file): tiles, Gaussians, the bytes of its chunk
  frames and their share of the file (``csgs info``'s figures), what a decode of that level
  alone reads (``bytes_read``: header, TOC, ``TIDX`` and its frames) and its share, the
  Python decode's seconds, the typical Gaussian size (median of the geometric mean of the two
  largest scales, world units, one sigma) and the tile-index estimate a page can make before
  decoding (median over the level's tiles of the cube root of box volume per Gaussian), the
  view width at which the typical size projects to 1.5 px at the orbit's distance, and the
  view widths at which the level reaches 30 and 35 dB against level 0;
- ``psnr``: per level of the file with the most levels and per view width, PSNR and
  foreground PSNR (pixels the level-0 render covers) of the level's render against level
  0's, averaged over ``--views`` orbit views at 20 degrees of elevation (numba rasterizer,
  black background, height 3/4 of the width).

Level 0 of a levels file codes exactly as the file of the same tiles without levels; the
benchmark checks that its decode equals that file's (``level0_equals_tiles_file``) before
using it as the reference.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import SCENES, document, emit  # noqa: E402

from csgs_codec import Decoder, Encoder, read_scene, write_scene  # noqa: E402
from csgs_codec.codec.describe import describe_bitstream  # noqa: E402
from csgs_codec.scene.gaussian_scene import GaussianScene  # noqa: E402
from csgs_codec.scene.orbit import guess_up_axis, orbit_cameras, robust_bounds  # noqa: E402

DEFAULT_SCENE = SCENES / "playbot.ply"
#: Gap between copies, as a share of a copy's robust width on that axis.
GAP = 0.25
#: Projected size (pixels) above which a viewer refines a tile (the page's rule).
REFINE_PX = 1.5
#: PSNR (dB) thresholds the level table lists the passing view widths for.
THRESHOLDS_DB = (30.0, 35.0)
ELEVATION_DEG = 20.0


def grid_copies(scene: GaussianScene, copies: int) -> GaussianScene:
    """``copies`` translated copies of ``scene`` on a ceil(sqrt(copies))-wide square grid
    across the two axes other than its up axis, :data:`GAP` of a copy's robust (2-98
    percentile) width apart, centred on the original."""
    up = int(np.argmax(np.abs(guess_up_axis(scene))))
    u, v = (axis for axis in range(3) if axis != up)
    low, high = robust_bounds(scene)
    step = (high - low) * (1.0 + GAP)
    side = int(np.ceil(np.sqrt(copies)))
    parts = []
    for k in range(copies):
        part = scene.subset(np.arange(len(scene)))
        shift = np.zeros(3)
        shift[u] = (k % side - (side - 1) / 2) * step[u]
        shift[v] = (k // side - (side - 1) / 2) * step[v]
        part.positions = (part.positions + shift).astype(np.float32)
        parts.append(part)
    return GaussianScene.concatenate(parts)


def build_scene(source: Path, copies: int, keep: int | None, folder: Path) -> GaussianScene:
    """The benchmark scene: ``copies`` of ``source`` (its first ``keep`` Gaussians when
    given) by :func:`grid_copies`, written to a PLY in ``folder`` and read back."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = read_scene(source)
        if keep is not None:
            scene = scene.subset(np.arange(min(keep, len(scene))))
        path = folder / "lod_scene.ply"
        write_scene(grid_copies(scene, copies), path)
        return read_scene(path)


def encode_row(name: str, encoder: Encoder, scene: GaussianScene) -> tuple[dict, bytes]:
    """(row, file) of one timed encode of ``scene``."""
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = encoder.encode(scene)
    seconds = time.perf_counter() - start
    facts = describe_bitstream(data, verify=False)
    return {"kind": "encode", "file": name, "tile_size": encoder.config.tile_size,
            "levels": encoder.config.levels, "tiles": facts.get("tiles", 1),
            "encode_s": round(seconds, 2), "bytes": len(data),
            "bits_per_gaussian": round(8 * len(data) / len(scene), 3),
            "sha256": hashlib.sha256(data).hexdigest()[:16]}, data


def typical_size(scene: GaussianScene) -> float:
    """Median over the Gaussians of the geometric mean of their two largest scales (world
    units, one sigma)."""
    scales = np.sort(np.exp(np.asarray(scene.scales, np.float64)), axis=1)
    return float(np.median(np.sqrt(scales[:, 1] * scales[:, 2])))


def tile_spacing(tiles) -> float:
    """Median over ``tiles`` (TileInfo of one level) of the cube root of box volume per
    Gaussian: the spacing a reader estimates from the tile index alone (world units)."""
    spacing = [(np.prod(np.maximum(np.subtract(t.upper, t.lower), 1e-12)) / t.count) ** (1 / 3)
               for t in tiles]
    return float(np.median(spacing))


def orbit_distance(scene: GaussianScene) -> tuple[float, float]:
    """(distance from an orbit camera to its look-at point, focal length per pixel of view
    width) of the views :func:`orbit_cameras` makes for ``scene``."""
    camera = orbit_cameras(scene, 1, width=1000, height=750, elevation_deg=ELEVATION_DEG)[0]
    low, high = robust_bounds(scene)
    centre = (low + high) / 2
    return float(np.linalg.norm(camera.position - centre)), camera.fx / camera.width


def level_rows(name: str, data: bytes, quiet: bool) -> tuple[list[dict], list[GaussianScene]]:
    """One ``level`` row per level of the file ``data`` (without the render figures) and
    the decoded level scenes, level 0 first."""
    from tqdm import tqdm

    from csgs_codec.chunks.tile_index import TileIndex
    from csgs_codec.format import read_layers

    facts = describe_bitstream(data, verify=False)
    container = read_layers(data, layers=set())
    tidx = next(e for e in container.toc if e.type == "TIDX")
    index = TileIndex.from_bytes(bytes(container.payloads[tidx.index]))
    rows, scenes = [], []
    for info in tqdm(facts["levels"], desc=f"decode {name}", disable=quiet):
        k = info["level"]
        start = time.perf_counter()
        report = Decoder().decode_with_report(data, lod=k)
        seconds = time.perf_counter() - start
        scenes.append(report.scene)
        rows.append({"kind": "level", "file": name, "level": k, "tiles": info["tiles"],
                     "gaussians": info["gaussians"], "bytes": info["bytes"],
                     "share_of_file": round(info["bytes"] / len(data), 5),
                     "bytes_read": report.bytes_read,
                     "read_share": round(report.bytes_read / len(data), 5),
                     "decode_s": round(seconds, 3),
                     "typical_size": typical_size(report.scene),
                     "tile_spacing": tile_spacing([index.tiles[i]
                                                   for i in index.level_tiles(k)])})
    return rows, scenes


def psnr_rows(name: str, scenes: list[GaussianScene], widths: list[int], views: int,
              quiet: bool) -> list[dict]:
    """One ``psnr`` row per level above 0 and view width: level k's renders against level
    0's over ``views`` orbit views (numba backend)."""
    from tqdm import tqdm

    from csgs_codec.metrics.image import foreground_mask, foreground_psnr, psnr
    from csgs_codec.render.rasterizer import render

    rows = []
    work = [(w, c) for w in widths for c in orbit_cameras(
        scenes[0], views, width=w, height=w * 3 // 4, elevation_deg=ELEVATION_DEG)]
    scores: dict[tuple[int, int], list[tuple[float, float, float]]] = {}
    for width, camera in tqdm(work, desc="render views", disable=quiet):
        reference = render(scenes[0], camera, backend="numba")
        image = np.clip(reference.image, 0, 1)
        mask = foreground_mask(reference.alpha)
        for k, scene in enumerate(scenes[1:], 1):
            start = time.perf_counter()
            out = render(scene, camera, backend="numba")
            seconds = time.perf_counter() - start
            other = np.clip(out.image, 0, 1)
            scores.setdefault((k, width), []).append(
                (psnr(image, other), foreground_psnr(image, other, mask), seconds))
    for (k, width), got in sorted(scores.items()):
        values = np.array(got)
        rows.append({"kind": "psnr", "file": name, "level": k, "width": width,
                     "height": width * 3 // 4, "views": len(got),
                     "psnr": round(float(values[:, 0].mean()), 3),
                     "foreground_psnr": round(float(np.nanmean(values[:, 1])), 3),
                     "render_s": round(float(values[:, 2].mean()), 3)})
    return rows


def widths_reaching(psnr_table: list[dict], level: int, threshold: float) -> list[int]:
    """The view widths (increasing) at which ``level``'s renders reach ``threshold`` dB
    (PSNR against level 0's) in ``psnr_table``'s rows."""
    return sorted(r["width"] for r in psnr_table if r["level"] == level
                  and r["psnr"] >= threshold)


def run(args) -> dict:
    """Build the scene, encode, decode and render; the csgs-bench/1 document."""
    from tqdm import tqdm

    with tempfile.TemporaryDirectory(prefix="csgs-lod-") as folder:
        scene = build_scene(Path(args.scene), args.copies, args.keep, Path(folder))
    encoders = [("single", Encoder()), ("tiles", Encoder(tile_size=args.tile_size))]
    encoders += [(f"levels{n}", Encoder(levels=n, tile_size=args.tile_size))
                 for n in args.levels]
    encodes, files = [], {}
    for name, encoder in tqdm(encoders, desc="encode", disable=args.quiet):
        row, files[name] = encode_row(name, encoder, scene)
        encodes.append(row)
    single, tiles = encodes[0]["bytes"], encodes[1]["bytes"]
    for row in encodes:
        row["ratio_to_single"] = round(row["bytes"] / single, 4)
        row["ratio_to_tiles"] = round(row["bytes"] / tiles, 4)
    levels, scenes = [], {}
    for name in files:
        if name.startswith("levels"):
            rows, scenes[name] = level_rows(name, files[name], args.quiet)
            levels += rows
    deepest = f"levels{max(args.levels)}"
    reference = Decoder().decode(files["tiles"])
    same = all(np.array_equal(getattr(reference, f), getattr(scenes[deepest][0], f))
               for f in ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations"))
    table = psnr_rows(deepest, scenes[deepest], args.widths, args.views, args.quiet)
    distance, focal_per_width = orbit_distance(scenes[deepest][0])
    for row in levels:
        # the view width at which the typical Gaussian spans REFINE_PX pixels at the
        # orbit's distance: width * focal_per_width * size / distance = REFINE_PX
        row["width_at_refine_px"] = round(REFINE_PX * distance
                                          / (focal_per_width * row["typical_size"]))
        row["typical_size"] = round(row["typical_size"], 6)
        row["tile_spacing"] = round(row["tile_spacing"], 6)
        for threshold in THRESHOLDS_DB:  # rendered: the deepest file's levels above 0
            key = f"widths_at_{threshold:g}db"
            row[key] = (widths_reaching(table, row["level"], threshold)
                        if row["level"] and row["file"] == deepest else None)
    coarse = [r for r in levels if r["file"] == deepest][-1]
    return document(
        "lod", encodes + levels + table, scene=Path(args.scene).stem, copies=args.copies,
        gaussians=len(scene), sh_degree=scene.sh_degree_in_use(),
        quality=describe_bitstream(files["single"], verify=False)["quality"],
        tile_size=args.tile_size, levels=args.levels, views=args.views, widths=args.widths,
        elevation_deg=ELEVATION_DEG, orbit_distance=round(distance, 4),
        focal_per_width=round(focal_per_width, 4), refine_px=REFINE_PX,
        level0_equals_tiles_file=bool(same),
        coarsest_read_share=coarse["read_share"],
        worst_ratio_to_single=max(r["ratio_to_single"] for r in encodes[2:]))


def main(argv: list[str] | None = None) -> int:
    """Parse the options, run, print or write the JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scene", default=str(DEFAULT_SCENE))
    parser.add_argument("--copies", type=int, default=9)
    parser.add_argument("--keep", type=int, default=None,
                        help="use the scene's first KEEP Gaussians (a small run)")
    parser.add_argument("--levels", type=int, nargs="+", default=[3, 4])
    parser.add_argument("--tile-size", type=int, default=65_536)
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--widths", type=int, nargs="+", default=[1600, 800, 400, 200])
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    if args.copies < 1 or min(args.levels) < 2 or args.views < 1:
        parser.error("--copies and --views must be >= 1 and every --levels >= 2")
    emit(run(args), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
