"""Stress scenes for the stability tests: extreme values, degenerate shapes, tiny and huge N.

Every builder returns a valid (finite) :class:`GaussianScene` of float32 arrays; the cases that
must be refused (NaN, Inf) are built from these by :func:`with_nonfinite`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from csgs_codec.scene.gaussian_scene import SH_REST_COUNTS, GaussianScene

#: Smallest positive float32 denormal and the largest float32 denormal.
DENORMAL_MIN = np.float32(1.4e-45)
DENORMAL_MAX = np.float32(1.1754942e-38)
#: Largest finite float16 value.
FLOAT16_MAX = np.float32(65504.0)
#: Gaussians in the default small stress scenes.
SMALL_N = 96


def plain_scene(n: int = SMALL_N, *, sh_degree: int = 1, seed: int = 0,
                extent: float = 1.0, centre: float = 0.0) -> GaussianScene:
    """A plausible random scene: positions uniform in a cube of side ``extent`` around
    ``centre`` (world units), unit-ish SH, opacity logits ~ N(0, 3), log-scales around -4
    relative to the extent, random (unnormalised) quaternions."""
    rng = np.random.default_rng(seed)
    bands = SH_REST_COUNTS[sh_degree]

    def normal(*shape: int, sigma: float = 1.0) -> np.ndarray:
        return (rng.normal(size=shape) * sigma).astype(np.float32)

    positions = centre + extent * rng.uniform(-0.5, 0.5, size=(n, 3))
    return GaussianScene(
        positions=positions.astype(np.float32),
        sh_dc=normal(n, 3),
        sh_rest=normal(n, bands, 3, sigma=0.1),
        opacity=normal(n, sigma=3.0),
        scales=(normal(n, 3, sigma=0.5) - 4 + np.log(extent)).astype(np.float32),
        rotations=normal(n, 4),
    )


def log_scales_full_range() -> GaussianScene:
    """Log-scales spread over [-30, 10], both ends included exactly."""
    scene = plain_scene()
    values = np.linspace(-30.0, 10.0, scene.scales.size).astype(np.float32)
    scene.scales = np.random.default_rng(1).permutation(values).reshape(-1, 3)
    return scene


def huge_opacity_logits() -> GaussianScene:
    """Opacity logits of +-1e4 mixed with ordinary ones (the codec clamps to +-10)."""
    scene = plain_scene()
    scene.opacity[::3] = 1e4
    scene.opacity[1::3] = -1e4
    return scene


def denormal_values() -> GaussianScene:
    """Subnormal float32 values in every float attribute (positions included)."""
    scene = plain_scene()
    tiny = np.array([DENORMAL_MIN, -DENORMAL_MIN, DENORMAL_MAX, -DENORMAL_MAX, 1e-40, -3e-42],
                    np.float32)
    for array in (scene.positions, scene.sh_dc, scene.sh_rest, scene.opacity, scene.scales,
                  scene.rotations):
        flat = array.reshape(-1)
        flat[: 3 * tiny.size: 3] = tiny
    # One Gaussian whose every value is a denormal (its quaternion has a subnormal norm).
    scene.rotations[-1] = DENORMAL_MIN
    scene.sh_dc[-1] = DENORMAL_MAX
    # Negative zeros keep their sign bit through PLY files.
    scene.sh_dc[-2] = -0.0
    scene.scales[-2, 0] = -0.0
    return scene


def float16_range_values() -> GaussianScene:
    """Values at +-65504 (the float16 limit) in SH, opacity and positions, and log-scales at
    +-88 (the encoder refuses log-scales beyond that)."""
    scene = plain_scene()
    scene.sh_dc[0] = FLOAT16_MAX
    scene.sh_dc[1] = -FLOAT16_MAX
    scene.sh_rest[2] = FLOAT16_MAX
    scene.sh_rest[3, 0] = -FLOAT16_MAX
    scene.opacity[4:6] = (FLOAT16_MAX, -FLOAT16_MAX)
    scene.scales[6] = 88.0
    scene.scales[7] = -88.0
    scene.positions[8] = FLOAT16_MAX
    scene.positions[9] = -FLOAT16_MAX
    scene.rotations[10] = (FLOAT16_MAX, -FLOAT16_MAX, FLOAT16_MAX, 1.0)
    return scene


def identical_gaussians() -> GaussianScene:
    """Every Gaussian the same, position included: every channel is constant."""
    one = plain_scene(1, seed=3)
    return one.subset(np.zeros(SMALL_N, np.int64))


def duplicate_positions() -> GaussianScene:
    """Distinct Gaussians stacked in groups of one to four on shared positions."""
    scene = plain_scene()
    groups = np.repeat(np.arange(SMALL_N // 2), 2)[:SMALL_N]
    groups[:8] = 0  # one position shared by eight Gaussians
    scene.positions = scene.positions[groups].copy()
    return scene


def empty_scene() -> GaussianScene:
    """N = 0 with SH degree 3 stored."""
    return GaussianScene.empty(sh_degree=3)


def single_gaussian() -> GaussianScene:
    """N = 1 with SH degree 3 in use."""
    return plain_scene(1, sh_degree=3, seed=5)


def tiny_extent() -> GaussianScene:
    """Positions within a 1e-6 cube around the origin."""
    return plain_scene(extent=1e-6)


def huge_extent() -> GaussianScene:
    """Positions within a 1e6 cube around the origin."""
    return plain_scene(extent=1e6)


def small_extent_far_from_origin() -> GaussianScene:
    """A 1-unit scene centred at 1e5 (float32 keeps about 0.008 units of precision there)."""
    return plain_scene(extent=1.0, centre=1e5)


def unnormalised_and_zero_quaternions() -> GaussianScene:
    """Quaternions of norm 1e-20 .. 1e20, exact zeros, and negative-w duplicates."""
    scene = plain_scene()
    norms = np.logspace(-20, 20, SMALL_N).astype(np.float32)
    unit = scene.rotations / np.linalg.norm(scene.rotations, axis=1, keepdims=True)
    scene.rotations = (unit * norms[:, None]).astype(np.float32)
    scene.rotations[::7] = 0.0
    scene.rotations[1::7] = -np.abs(scene.rotations[1::7])
    scene.rotations[2] = (0.0, 0.0, 0.0, -3.0)
    scene.rotations[3] = (0.5, 0.5, 0.5, 0.5)  # a four-way tie for the largest component
    return scene


def far_outlier() -> GaussianScene:
    """Dense points in a unit cube plus one Gaussian 1e7 units away."""
    scene = plain_scene(400, seed=7)
    scene.positions[123] = (1e7, -2e7, 3e7)
    return scene


def far_outlier_among_few() -> GaussianScene:
    """48 points in a unit cube plus one Gaussian 1e7 units away (2% of the scene)."""
    scene = plain_scene(49, seed=11)
    scene.positions[30] = (-1e7, 1e7, 0.5)
    return scene


def far_outlier_at_float32_limit() -> GaussianScene:
    """Dense points in a unit cube plus one Gaussian near the largest float32."""
    scene = plain_scene(400, seed=8)
    scene.positions[17] = (3e38, -3e38, 1.0)
    return scene


def with_semantic(scene: GaussianScene, channels: int = 3, seed: int = 0) -> GaussianScene:
    """``scene`` with ``channels`` random semantic features (ins_feat_*) and labels added."""
    rng = np.random.default_rng(seed)
    n = len(scene)
    scene.semantic = rng.normal(size=(n, channels)).astype(np.float32)
    scene.semantic_names = tuple(f"ins_feat_{i}" for i in range(channels))
    scene.labels = rng.integers(0, 5, size=n).astype(np.int32)
    return scene


def semantic_extremes() -> GaussianScene:
    """Semantic features with denormals, zeros and +-65504, labels at the int32 limits."""
    scene = with_semantic(plain_scene(), channels=4, seed=9)
    scene.semantic[:4, 0] = (DENORMAL_MIN, -DENORMAL_MAX, FLOAT16_MAX, -FLOAT16_MAX)
    scene.semantic[:, 1] = 0.0
    scene.labels[:3] = (np.iinfo(np.int32).max, np.iinfo(np.int32).min, 0)
    return scene


#: Name -> builder of every finite stress scene.
STRESS_SCENES: dict[str, Callable[[], GaussianScene]] = {
    "plain": plain_scene,
    "log_scales_-30_to_10": log_scales_full_range,
    "opacity_logits_1e4": huge_opacity_logits,
    "denormals": denormal_values,
    "float16_range": float16_range_values,
    "identical_gaussians": identical_gaussians,
    "duplicate_positions": duplicate_positions,
    "n0": empty_scene,
    "n1": single_gaussian,
    "extent_1e-6": tiny_extent,
    "extent_1e6": huge_extent,
    "extent_1_at_1e5": small_extent_far_from_origin,
    "unnormalised_zero_quaternions": unnormalised_and_zero_quaternions,
    "far_outlier_1e7": far_outlier,
    "far_outlier_3e38": far_outlier_at_float32_limit,
    "far_outlier_among_49": far_outlier_among_few,
    "semantic_extremes": semantic_extremes,
}

#: Float attributes of a scene that NaN/Inf can be written into.
ATTRIBUTES = ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations", "semantic")


def with_nonfinite(attribute: str, value: float, index: int = 5) -> GaussianScene:
    """A small scene (SH degree 1, semantic channels) with ``value`` (NaN or +-Inf) written
    into Gaussian ``index`` of ``attribute``."""
    scene = with_semantic(plain_scene())
    array = getattr(scene, attribute)
    array.reshape(len(scene), -1)[index, -1] = value
    return scene
