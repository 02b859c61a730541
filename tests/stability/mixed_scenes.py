"""Random scenes that mix every stress at once, for property-based stability sweeps."""

from __future__ import annotations

import numpy as np

from csgs_codec.scene.gaussian_scene import GaussianScene
from tests.stability.stress_scenes import DENORMAL_MAX, DENORMAL_MIN, FLOAT16_MAX, plain_scene

#: Values that replace a random share of each attribute's entries.
SPECIAL_VALUES = np.array([0.0, -0.0, DENORMAL_MIN, -DENORMAL_MIN, DENORMAL_MAX, FLOAT16_MAX,
                           -FLOAT16_MAX], np.float32)
#: The same for log-scales, whose range the encoder limits to +-88 (issue #20).
SCALE_SPECIAL_VALUES = np.where(np.abs(SPECIAL_VALUES) > 88, np.sign(SPECIAL_VALUES) * 88,
                                SPECIAL_VALUES).astype(np.float32)


def mixed_scene(seed: int, n: int, sh_degree: int) -> GaussianScene:
    """A scene of ``n`` Gaussians (SH degree ``sh_degree``) with, chosen by ``seed``: an
    extent of 1e-6 .. 1e6 units, duplicated positions, at most one far outlier, log-scales in
    [-30, 10], opacity logits up to +-1e4, zero and unnormalised quaternions, and a few special
    values (zeros, denormals, +-65504; +-88 in log-scales, the encoder's limit) sprinkled over
    every attribute except positions."""
    rng = np.random.default_rng(seed)
    extent = float(10.0 ** rng.uniform(-6, 6))
    scene = plain_scene(n, sh_degree=sh_degree, seed=seed, extent=extent,
                        centre=float(rng.choice([0.0, 100 * extent])))
    if n == 0:
        return scene
    if rng.random() < 0.5:
        scene.scales = rng.uniform(-30, 10, size=(n, 3)).astype(np.float32)
    if rng.random() < 0.5:
        scene.opacity = rng.choice([-1e4, -10.0, 0.0, 10.0, 1e4], size=n).astype(np.float32)
    if rng.random() < 0.5:
        norms = 10.0 ** rng.uniform(-20, 20, size=(n, 1))
        scene.rotations = (scene.rotations * norms).astype(np.float32)
    if rng.random() < 0.3:
        scene.rotations[rng.random(n) < 0.3] = 0.0
    if rng.random() < 0.3:
        source = rng.integers(0, n, size=n)
        keep = rng.random(n) < 0.5
        scene.positions[keep] = scene.positions[source[keep]]
    if rng.random() < 0.3:
        scene.positions[rng.integers(0, n)] = rng.choice([-1.0, 1.0], size=3) * 1e7 * extent
    for array in (scene.sh_dc, scene.sh_rest, scene.opacity, scene.scales, scene.rotations):
        flat = array.reshape(-1)
        if flat.size and rng.random() < 0.5:
            where = rng.random(flat.size) < 0.05
            specials = SCALE_SPECIAL_VALUES if array is scene.scales else SPECIAL_VALUES
            flat[where] = rng.choice(specials, size=int(where.sum()))
    return scene
