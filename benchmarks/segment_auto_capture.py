"""The mary_rose part of benchmarks/segment_auto.py: a click on the object of a real capture
trained without instance masks (module notes of segment_auto.py, ``--mary-rose``).

    python benchmarks/segment_auto_capture.py [--csgs FILE] [--out FILE]

``--csgs`` clicks an already trained file instead of training one (the same settings).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_common import REPO, document, emit  # noqa: E402

CAPTURE = REPO.parent / "shared" / "data" / "captures" / "mary_rose"
RESOLUTION = 384
TEST_EVERY = 8


def train(output: Path) -> dict:
    """``csgs train CAPTURE --resolution 384 --builtin-segmenter -o output``; its facts."""
    began = time.perf_counter()
    subprocess.run([sys.executable, "-m", "csgs_cli.main", "train", str(CAPTURE),
                    "--resolution", str(RESOLUTION), "--builtin-segmenter", "--quiet",
                    "-o", str(output)], check=True, cwd=REPO)
    return {"train_seconds": round(time.perf_counter() - began, 1)}


def click_point(foreground: np.ndarray) -> tuple[float, float]:
    """The centre (x, y) of the foreground pixel nearest the foreground's centroid."""
    rows, cols = np.nonzero(foreground)
    centre = np.array([rows.mean(), cols.mean()])
    nearest = int(np.argmin((rows - centre[0]) ** 2 + (cols - centre[1]) ** 2))
    return cols[nearest] + 0.5, rows[nearest] + 0.5


def selected_pixels(scene, selected: np.ndarray, camera) -> np.ndarray:
    """(H, W) bool: pixels where the selected anchors' Gaussians carry more rendered weight
    than the other Gaussians and than the background (final transmittance)."""
    from csgs_codec.model.scaffold import ScaffoldDecoder
    from csgs_codec.render.rasterizer import render

    decoded = ScaffoldDecoder(scene).decode(camera.position)
    chosen = selected[decoded.anchor_index]
    one_hot = np.stack([chosen, ~chosen], axis=1).astype(np.float32)
    out = render(decoded.gaussians, camera, features=one_hot)
    weights = out.features
    return (weights[..., 0] > weights[..., 1]) & (weights[..., 0] > 1.0 - out.alpha)


def measure_mary_rose(csgs: str | None = None) -> dict:
    """Train (unless ``csgs``), decode, click every held-out photo: the result row."""
    from csgs_cli.dataset_input import downscale_for
    from csgs_codec.codec.anchor_decoder import AnchorDecoder
    from csgs_codec.errors import InputError
    from csgs_codec.semantic.evaluation import mask_iou
    from csgs_codec.semantic.selection import click_selection
    from csgs_codec.train.datasets import find_foreground_masks, load_dataset
    from csgs_codec.train.evaluation import split_views

    row = {"scene": "mary_rose", "variant": "builtin", "resolution": RESOLUTION}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(csgs) if csgs else Path(folder) / "mary_rose.csgs"
        if not csgs:
            row.update(train(path))
        data = path.read_bytes()
    scene = AnchorDecoder().decode(data, layers="color,semantic")
    views = load_dataset(CAPTURE, downscale=downscale_for(str(CAPTURE), RESOLUTION),
                         read_masks=False, foreground=find_foreground_masks(CAPTURE))
    _, held_out = split_views(views, TEST_EVERY)
    ious = []
    for view in held_out:
        x, y = click_point(view.foreground)
        try:
            selection = click_selection(scene, view.camera, x, y)
        except InputError:  # the click hit nothing
            ious.append(0.0)
            continue
        ious.append(mask_iou(selected_pixels(scene, selection.mask, view.camera).ravel(),
                             view.foreground.ravel()))
    ids = np.unique(scene.semantic, axis=0)
    row.update(file_bytes=len(data), anchors=len(scene), distinct_features=len(ids),
               held_out_views=len(held_out), click_iou_2d=[round(v, 4) for v in ious],
               click_miou_2d=float(np.mean(ious)), click_min_iou_2d=float(np.min(ious)))
    print(f"mary_rose: click mIoU 2D {row['click_miou_2d']:.3f} (min "
          f"{row['click_min_iou_2d']:.3f}) over {len(held_out)} held-out photos",
          file=sys.stderr)
    return row


def main() -> int:
    """Parse arguments, run, print or write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--csgs", help="a file csgs train already wrote (same settings)")
    parser.add_argument("--notes", default="")
    parser.add_argument("--out")
    args = parser.parse_args()
    emit(document("segment_auto", [measure_mary_rose(args.csgs)], notes=args.notes), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
