"""Whether a scene codes smaller with each Gaussian's axes sorted by scale (encoder only).

A Gaussian's axes can be listed in any order (with its rotation turned to match, the same
covariance), so the encoder may code them largest scale first: the three log-scales then
carry no order and cost about log2(6) bits a Gaussian less. That pays where rotations are
spread over the sphere (captures trained from random or SfM points: leica_sofort_top8192 and
yashica_t4_top8192 code their scales 2.8 bits a Gaussian smaller, their rotations as before),
and not where most Gaussians keep a rotation near the identity (biker: its rotations then
cost what the scales save and come back less precise). So the encoder plans both on a sample
of the scene at the preset's steps and sorts when the sorted form needs fewer bits once a
rotation error it makes larger is charged for: BITS_PER_ERROR_DOUBLING a Gaussian for each
doubling of the rotations' mean squared error. High-rate theory would charge 1.5 bits (half a
bit for each of three coded components); measured encodes charge more, because a less
precise rotation costs image quality the plan does not see: sorted, biker's planned bits fell
1.0 bits a Gaussian for 18% more rotation error, and its default encodes lost 0.13-0.32 dB
held-out for 0.2-1.5% fewer bytes, while the sample (donut: 1.3 bits for 10%) coded 1.7-2.3%
smaller at the same PSNR. 6 bits a doubling separates the two. (Those figures were measured
without the guard of :func:`canonical_orientations`, which keeps the axes of Gaussians whose
turned rotation would be imprecise; with it the plan still sorts the three SH-3 captures at
every quality and leaves biker.)
"""

from __future__ import annotations

import numpy as np

from csgs_codec.attributes.attribute_forms import (
    canonical_orientations,
    canonical_rotations,
    quaternion_to_smallest_three,
    smallest_three_to_quaternion,
)
from csgs_codec.attributes.float_stream import plan_float_stream
from csgs_codec.decisions.presets import Preset
from csgs_codec.scene.gaussian_scene import GaussianScene

#: Gaussians the decision plans on at most (a seeded sample of larger scenes).
SAMPLE = 65_536
#: Bits a Gaussian one doubling of the rotations' mean squared error is charged (module notes).
BITS_PER_ERROR_DOUBLING = 6.0


def sorted_axes_pay(scene: GaussianScene, preset: Preset) -> bool:
    """True when ``scene`` codes its scales and rotations in fewer bits at equal rotation
    error with every Gaussian's axes sorted by scale (largest first), at ``preset``'s scale
    and rotation steps (one step for all; see the module notes)."""
    n = len(scene)
    if n < 2:
        return False
    rows = (np.sort(np.random.default_rng(0).choice(n, SAMPLE, replace=False))
            if n > SAMPLE else slice(None))
    rotations, scales = scene.rotations[rows], scene.scales[rows]
    kept = _cost(canonical_rotations(rotations), scales.astype(np.float32), preset)
    turned, sorted_scales = canonical_orientations(rotations, scales)
    moved = _cost(turned, sorted_scales, preset)
    count = len(sorted_scales)
    penalty = BITS_PER_ERROR_DOUBLING * count * np.log2(max(moved[1], 1e-30)
                                                        / max(kept[1], 1e-30))
    return bool(moved[0] + penalty < kept[0])


def _cost(rotations: np.ndarray, scales: np.ndarray, preset: Preset) -> tuple[float, float]:
    """(planned bits of the scale and rotation streams, mean squared rotation error in
    radians^2) of canonical ``rotations`` (N, 4) and log-``scales`` (N, 3)."""
    axis, rest = quaternion_to_smallest_three(rotations)
    scale_plan = plan_float_stream(scales, preset.scale_step)
    rotation_plan = plan_float_stream(rest, preset.rotation_step)
    bits = sum(ch.cost for ch in scale_plan.channels + rotation_plan.channels)
    decoded = smallest_three_to_quaternion(axis, rotation_plan.recon).astype(np.float64)
    cosine = np.clip(np.abs(np.sum(decoded * rotations.astype(np.float64), axis=1)), 0.0, 1.0)
    angle = 2.0 * np.arccos(cosine)
    return float(bits), float(np.mean(angle * angle))
