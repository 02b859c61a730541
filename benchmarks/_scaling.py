"""Scenes of a chosen size made from a real one: seeded subsets and jittered upsampling.

The speed benchmark measures the codec from 10k to 2M Gaussians; the shared scenes hold at
most 248k, so larger sizes add jittered copies of real Gaussians. Both constructions are pure
functions of (scene, size, seed), so a run is reproducible on any machine.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from csgs_codec import GaussianScene

#: Array attributes of a color-only GaussianScene, in the order they are saved.
SCENE_ARRAYS = ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations")
#: Standard deviation of a copy's position jitter, as a fraction of the source Gaussian's
#: mean world-unit scale: small enough that copies stay inside the object's surface.
JITTER_FRACTION = 0.5


def color_only(scene: GaussianScene) -> GaussianScene:
    """``scene`` without its semantic channels and labels (the arrays are shared)."""
    return GaussianScene(**{name: getattr(scene, name) for name in SCENE_ARRAYS})


def subset_of_size(scene: GaussianScene, count: int, seed: int) -> GaussianScene:
    """``count`` Gaussians of ``scene`` drawn without replacement, in file order.

    Args:
        scene: the source scene (N Gaussians).
        count: 0 <= count <= N.
        seed: seed of the draw; the same seed gives the same subset everywhere.
    """
    if not 0 <= count <= len(scene):
        raise ValueError(f"a subset of {count} from {len(scene)} Gaussians")
    if count == len(scene):
        return color_only(scene)
    rng = np.random.default_rng(seed)
    keep = np.sort(rng.choice(len(scene), size=count, replace=False))
    return color_only(scene.subset(keep))


def upsampled_to(scene: GaussianScene, count: int, seed: int,
                 jitter_fraction: float = JITTER_FRACTION) -> GaussianScene:
    """``scene`` plus ``count - N`` jittered copies of its Gaussians.

    Copies are taken in a seeded random order of the sources, cycling through all of them
    before any is copied twice. A copy keeps every attribute of its source except the
    position, which moves by normal noise (world units) with standard deviation
    ``jitter_fraction * exp(mean log-scale)`` per axis.

    Args:
        scene: the source scene (N >= 1 Gaussians).
        count: total Gaussians wanted, >= N.
        seed: seed of the copy order and the jitter.
    """
    n = len(scene)
    if n == 0 or count < n:
        raise ValueError(f"upsampling {n} Gaussians to {count}")
    extra = count - n
    rng = np.random.default_rng(seed)
    rounds = -(-extra // n)
    sources = np.concatenate([rng.permutation(n) for _ in range(rounds)])[:extra]
    copies = color_only(scene.subset(sources))
    spread = jitter_fraction * np.exp(copies.scales.astype(np.float64).mean(axis=1))
    noise = rng.standard_normal((extra, 3)) * spread[:, None]
    copies.positions = (copies.positions.astype(np.float64) + noise).astype(np.float32)
    base = color_only(scene)
    return GaussianScene(**{name: np.concatenate([getattr(base, name), getattr(copies, name)])
                            for name in SCENE_ARRAYS})


def scene_of_size(scene: GaussianScene, count: int, seed: int) -> tuple[GaussianScene, str]:
    """A scene of exactly ``count`` Gaussians made from ``scene``, and how it was made.

    Returns:
        (scene, construction) where construction is "full", "subset" or "upsampled".
    """
    if count == len(scene):
        return color_only(scene), "full"
    if count < len(scene):
        return subset_of_size(scene, count, seed), "subset"
    return upsampled_to(scene, count, seed), "upsampled"


def save_arrays(scene: GaussianScene, folder: Path) -> None:
    """Write the scene's arrays as one .npy file each under ``folder`` (created)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in SCENE_ARRAYS:
        np.save(folder / f"{name}.npy", getattr(scene, name))


def load_arrays(folder: Path) -> GaussianScene:
    """The scene :func:`save_arrays` wrote, read without intermediate copies."""
    return GaussianScene(**{name: np.load(folder / f"{name}.npy") for name in SCENE_ARRAYS})
