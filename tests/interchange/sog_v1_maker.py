"""Writes a SOG v1 folder (the retired per-channel min/max layout) for the reader's tests.

No public tool writes v1 any more, so this helper makes the fixture
``tests/data/formats/brush_sh1_sog_v1``; splat-transform 3.7.0,
which still reads v1, decodes it to ``oracle/brush_sh1_sog_v1.ply`` as the independent check.
Run ``python -m tests.interchange.sog_v1_maker`` to remake it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.scene.gaussian_scene import GaussianScene

DATA = Path(__file__).resolve().parents[1] / "data" / "formats"
WIDTH = 16


def _texture(rows: np.ndarray, folder: Path, name: str) -> str:
    """Save (N, 4) uint8 rows as a lossless WebP of WIDTH columns, row-major."""
    height = -(-len(rows) // WIDTH)
    pixels = np.zeros((WIDTH * height, 4), np.uint8)
    pixels[:len(rows)] = rows
    Image.fromarray(pixels.reshape(height, WIDTH, 4), "RGBA").save(
        folder / name, lossless=True, quality=100, exact=True)
    return name


def _byte(values: np.ndarray, lo, hi) -> np.ndarray:
    span = np.where(np.asarray(hi) - lo == 0, 1.0, np.asarray(hi) - lo)
    return np.clip(np.rint((values - lo) / span * 255.0), 0, 255).astype(np.uint8)


def write_sog_v1(scene: GaussianScene, folder: Path) -> None:
    """Write ``scene`` (SH degree 0 or 1) as a SOG v1 folder: one palette entry per
    Gaussian, so only the 8-bit quantization of each attribute is lost."""
    folder.mkdir(parents=True, exist_ok=True)
    n = len(scene)
    opaque = np.full((n, 1), 255, np.uint8)
    log_pos = np.sign(scene.positions) * np.log1p(np.abs(scene.positions.astype(np.float64)))
    lo, hi = log_pos.min(axis=0), log_pos.max(axis=0)
    q = np.rint((log_pos - lo) / np.where(hi - lo == 0, 1, hi - lo) * 65535).astype(np.int64)
    meta = {"means": {"shape": [n, 3], "dtype": "float32", "mins": lo.tolist(),
                      "maxs": hi.tolist(),
                      "files": [_texture(np.hstack([(q & 255).astype(np.uint8), opaque]),
                                         folder, "means_l.webp"),
                                _texture(np.hstack([(q >> 8).astype(np.uint8), opaque]),
                                         folder, "means_u.webp")]}}
    s_lo, s_hi = scene.scales.min(axis=0), scene.scales.max(axis=0)
    meta["scales"] = {"shape": [n, 3], "dtype": "float32", "mins": s_lo.tolist(),
                      "maxs": s_hi.tolist(),
                      "files": [_texture(np.hstack([_byte(scene.scales, s_lo, s_hi), opaque]),
                                         folder, "scales.webp")]}
    q = scene.rotations / np.linalg.norm(scene.rotations, axis=1, keepdims=True)
    largest = np.argmax(np.abs(q), axis=1)
    q = q * np.where(q[np.arange(n), largest] < 0, -1.0, 1.0)[:, None]
    others = np.stack([np.delete(row, m) for row, m in zip(q, largest)])
    quats = np.hstack([np.clip(np.rint((others * np.sqrt(2) + 1) / 2 * 255), 0, 255),
                       (252 + largest)[:, None]]).astype(np.uint8)
    meta["quats"] = {"shape": [n, 4], "dtype": "uint8", "encoding": "quaternion_packed",
                     "files": [_texture(quats, folder, "quats.webp")]}
    color = np.hstack([scene.sh_dc, scene.opacity[:, None]]).astype(np.float64)
    c_lo, c_hi = color.min(axis=0), color.max(axis=0)
    meta["sh0"] = {"shape": [n, 1, 4], "dtype": "float32", "mins": c_lo.tolist(),
                   "maxs": c_hi.tolist(),
                   "files": [_texture(_byte(color, c_lo, c_hi), folder, "sh0.webp")]}
    if scene.sh_rest.shape[1]:
        rest = scene.sh_rest[:, :3, :].astype(np.float64)  # degree 1: 3 coefficients
        r_lo, r_hi = float(rest.min()), float(rest.max())
        rows = -(-n // 64)
        centroids = np.zeros((rows * 64, 3, 4), np.uint8)
        centroids[:n, :, :3] = _byte(rest, r_lo, r_hi)
        centroids[:, :, 3] = 255
        image = centroids.reshape(rows, 64 * 3, 4)
        Image.fromarray(image, "RGBA").save(folder / "shN_centroids.webp", lossless=True,
                                            quality=100, exact=True)
        labels = np.zeros((n, 4), np.uint8)
        labels[:, 0], labels[:, 1], labels[:, 3] = np.arange(n) & 255, np.arange(n) >> 8, 255
        meta["shN"] = {"shape": [n, 3, 3], "dtype": "float32", "mins": r_lo, "maxs": r_hi,
                       "quantization": 8,
                       "files": ["shN_centroids.webp", _texture(labels, folder,
                                                                "shN_labels.webp")]}
    (folder / "meta.json").write_text(json.dumps(meta, indent=1))


def first_degree(scene: GaussianScene) -> GaussianScene:
    """``scene`` with its SH cut to degree 1."""
    cut = scene.subset(np.arange(len(scene)))
    cut.sh_rest = np.ascontiguousarray(scene.sh_rest[:, :3, :])
    return cut


if __name__ == "__main__":
    write_sog_v1(first_degree(read_ply(DATA / "brush_sh3.ply")), DATA / "brush_sh1_sog_v1")
