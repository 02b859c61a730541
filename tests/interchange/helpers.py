"""Shared pieces of the interchange tests: fixture paths, splat-transform's decodings (the
oracles) and comparisons in the units each format quantizes."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from csgs_codec.interchange.binary import dc_to_color, logit_to_alpha
from csgs_codec.interchange.ply_reader import read_vertex_columns
from csgs_codec.scene.gaussian_scene import GaussianScene

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data" / "formats"
ORACLE = DATA / "oracle"
SPLAT_TRANSFORM = (REPO / "benchmarks" / "node_modules" / "@playcanvas" / "splat-transform"
                   / "bin" / "cli.mjs")


def oracle_columns(name: str) -> dict[str, np.ndarray]:
    """The PLY columns splat-transform 3.7.0 decoded from fixture ``name`` (float64)."""
    stem = name.replace("/meta.json", "").replace(".", "_")
    _, _, columns = read_vertex_columns((ORACLE / f"{stem}.ply").read_bytes())
    return {key: np.asarray(value, np.float64) for key, value in columns.items()}


def oracle_scene_arrays(columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Oracle columns as scene-shaped arrays (sh_rest (N, B, 3) coefficient-major)."""
    n = len(columns["x"])
    rest = sum(1 for k in columns if k.startswith("f_rest_"))
    sh = np.stack([columns[f"f_rest_{i}"] for i in range(rest)], axis=1) if rest else \
        np.zeros((n, 0))
    return {
        "positions": np.stack([columns[a] for a in "xyz"], axis=1),
        "sh_dc": np.stack([columns[f"f_dc_{i}"] for i in range(3)], axis=1),
        "sh_rest": sh.reshape(n, 3, rest // 3).transpose(0, 2, 1),
        "opacity": columns["opacity"],
        "scales": np.stack([columns[f"scale_{i}"] for i in range(3)], axis=1),
        "rotations": np.stack([columns[f"rot_{i}"] for i in range(4)], axis=1),
    }


def matched(source: GaussianScene, scene: GaussianScene) -> GaussianScene:
    """The Gaussians of ``source`` nearest to each of ``scene``'s (files may reorder or drop
    Gaussians), asserting the match is one to one."""
    a = scene.positions.astype(np.float64)
    b = source.positions.astype(np.float64)
    nearest = np.argmin(((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2), axis=1)
    assert len(set(nearest.tolist())) == len(scene), "positions do not match one to one"
    return source.subset(nearest)


def rotation_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """1 - |<a, b>| of the normalised quaternions, per row (0 for the same rotation)."""
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    return 1.0 - np.abs(np.sum(a.astype(np.float64) * b, axis=1))


def colors(scene: GaussianScene) -> np.ndarray:
    """Diffuse color 0.5 + SH_C0 f_dc (unclamped)."""
    return dc_to_color(scene.sh_dc)


def alphas(scene: GaussianScene) -> np.ndarray:
    """sigmoid(opacity)."""
    return logit_to_alpha(scene.opacity)


def splat_transform_or_skip() -> list[str]:
    """The command that runs splat-transform, or skip the test saying what is missing."""
    if shutil.which("node") is None:
        pytest.skip("node (Node.js) is not on PATH")
    if not SPLAT_TRANSFORM.is_file():
        pytest.skip("@playcanvas/splat-transform is not installed (run `npm ci` in "
                    "benchmarks/)")
    return ["node", str(SPLAT_TRANSFORM), "--quiet", "--overwrite", "--gpu", "cpu"]


def splat_transform(*args: str) -> None:
    """Run splat-transform with ``args`` (skipping the test when it is not installed)."""
    command = splat_transform_or_skip() + [str(a) for a in args]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
