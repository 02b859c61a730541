"""Seed captures for the dataset-loader fuzzer: one tiny real capture (3 views of 8x6 px
images with instance masks) in each layout :func:`csgs_codec.train.datasets.load_dataset`
reads, written by the tests' own writers and held as {relative path: bytes}.

``format`` names the layout ("transforms", "inria", "colmap-text", "colmap-binary",
"llff"); ``camera`` is the camera file's relative path (for COLMAP, ``sparse/0/images.*``,
whose folder is the model).
"""

from __future__ import annotations

import functools
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgs_codec.render.image_io import save_png
from csgs_codec.train.synthetic import make_synthetic_dataset, write_transforms_dataset
from tests.train.layouts import write_colmap, write_inria

FORMATS = ("transforms", "inria", "colmap-text", "colmap-binary", "llff")
VIEWS, WIDTH, HEIGHT = 3, 8, 6


@dataclass(frozen=True)
class LoaderSeed:
    """One capture: its name, layout, camera file (relative path) and files."""

    name: str
    format: str
    camera: str
    files: dict[str, bytes]

    @property
    def size(self) -> int:
        """Bytes in all the capture's files."""
        return sum(len(data) for data in self.files.values())


def _llff_rows(cameras) -> np.ndarray:
    """(N, 17) poses_bounds rows (LLFF's columns: down, right, back, centre, hwf; near, far)."""
    rows = []
    for camera in cameras:
        c2w = camera.camera_to_world
        matrix = np.column_stack([c2w[:3, 1], c2w[:3, 0], -c2w[:3, 2], c2w[:3, 3],
                                  [camera.height, camera.width, camera.fx]])
        rows.append(np.concatenate([matrix.ravel(), [0.5, 9.0]]))
    return np.asarray(rows)


def _write_masks(views, root: Path, stems: list[str]) -> None:
    (root / "masks").mkdir(parents=True, exist_ok=True)
    for view, stem in zip(views, stems):
        save_png(view.mask.astype(np.uint8), root / "masks" / f"{stem}.png")


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file()}


@functools.lru_cache(maxsize=1)
def _loader_seeds() -> tuple[LoaderSeed, ...]:
    views = make_synthetic_dataset(3, objects=2, gaussians_per_object=20, views=VIEWS,
                                   width=WIDTH, height=HEIGHT).views
    stems = [f"view_{i:03d}" for i in range(VIEWS)]
    seeds = []
    with tempfile.TemporaryDirectory(prefix="csgs_loader_seeds_") as scratch:
        base = Path(scratch)
        write_transforms_dataset(views, base / "transforms")
        seeds.append(LoaderSeed("transforms", "transforms", "transforms.json",
                                _files(base / "transforms")))
        write_inria(views, base / "inria")
        _write_masks(views, base / "inria", stems)
        seeds.append(LoaderSeed("inria", "inria", "cameras.json", _files(base / "inria")))
        for binary, fmt in ((False, "colmap-text"), (True, "colmap-binary")):
            write_colmap(views, base / fmt, binary=binary)
            _write_masks(views, base / fmt, stems)
            camera = f"sparse/0/images.{'bin' if binary else 'txt'}"
            seeds.append(LoaderSeed(fmt, fmt, camera, _files(base / fmt)))
        llff = base / "llff"
        (llff / "images").mkdir(parents=True)
        for view, stem in zip(views, stems):
            save_png(view.image, llff / "images" / f"{stem}.png")
        np.save(llff / "poses_bounds.npy", _llff_rows([v.camera for v in views]))
        _write_masks(views, llff, stems)
        seeds.append(LoaderSeed("llff", "llff", "poses_bounds.npy", _files(llff)))
    return tuple(seeds)


def loader_seeds() -> list[LoaderSeed]:
    """Every seed capture, in :data:`FORMATS` order (made once per process)."""
    return list(_loader_seeds())
