"""Split a scene into the attribute streams the color layer codes, and join them back.

A stream is one attribute type in its coding form (see csgs_codec/attributes/attribute_forms.py):

    dc        (N, 3)            SH degree-0 coefficients
    rest1..3  (N, 3 * (2b+1))   SH band b coefficients, only for bands 1..degree in use
    opacity   (N, 1)            opacity logits clamped to +-10
    scale     (N, 3)            natural-log scales
    rot       (N, 3)            smallest-three rotation components in [-1, 1]
    rot_axis  (N,)  uint8       which quaternion component was dropped (0..3)

Channels whose value is identical for every Gaussian are not coded: their value travels in the
scene header (:class:`ConstantChannel`) and costs no bits per Gaussian; so do all-zero SH bands.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.attributes.attribute_forms import (
    canonical_orientations,
    canonical_rotations,
    clamp_opacity_logits,
    quaternion_to_smallest_three,
    smallest_three_to_quaternion,
)
from csgs_codec.scene.gaussian_scene import SH_REST_COUNTS, GaussianScene

FLOAT_STREAMS = ("dc", "rest1", "rest2", "rest3", "opacity", "scale", "rot")


@dataclass(frozen=True)
class ConstantChannel:
    """A channel of a float stream that holds one value for every Gaussian (float32)."""

    stream: str
    channel: int
    value: float


@dataclass
class SceneStreams:
    """The streams of one scene in coding order (N Gaussians, canonical order already applied).

    Attributes:
        float_streams: name -> (N, C) float32 values in coding form, bands not in use absent.
        rot_axis: (N,) uint8 dropped-component index of each rotation.
        sh_degree_stored: SH degree the decoded scene stores (higher bands decode as zeros).
    """

    float_streams: dict[str, np.ndarray]
    rot_axis: np.ndarray
    sh_degree_stored: int

    @property
    def count(self) -> int:
        """Number of Gaussians N."""
        return int(self.rot_axis.shape[0])


def split_streams(scene: GaussianScene, sort_axes: bool = False) -> SceneStreams:
    """The coding-form streams of ``scene`` (no quantization here): rotations in the form of
    :func:`canonical_rotations`, and with ``sort_axes`` each Gaussian's axes sorted by scale
    first (:func:`canonical_orientations`; :mod:`csgs_codec.decisions.axis_order` says when
    that pays)."""
    n = len(scene)
    streams = {"dc": scene.sh_dc.astype(np.float32)}
    for band in range(1, scene.sh_degree_in_use() + 1):
        lo, hi = SH_REST_COUNTS[band - 1], SH_REST_COUNTS[band]
        streams[f"rest{band}"] = np.ascontiguousarray(
            scene.sh_rest[:, lo:hi, :].reshape(n, (hi - lo) * 3))
    streams["opacity"] = clamp_opacity_logits(scene.opacity).reshape(n, 1)
    # The same Gaussians with w the largest component of their rotation (the axis stream is
    # then constant) and, if asked, their scales sorted (their order is then not coded).
    if sort_axes:
        rotations, scales = canonical_orientations(scene.rotations, scene.scales)
    else:
        rotations, scales = canonical_rotations(scene.rotations), scene.scales
    streams["scale"] = scales.astype(np.float32)
    axis, rest = quaternion_to_smallest_three(rotations)
    streams["rot"] = rest
    return SceneStreams(streams, axis, scene.sh_degree_stored)


def constant_channels(streams: SceneStreams) -> list[ConstantChannel]:
    """Channels (of float streams) with the same value for every Gaussian; none when N = 0."""
    out = []
    if streams.count == 0:
        return out
    for name, values in streams.float_streams.items():
        same = np.all(values == values[:1], axis=0)
        out += [ConstantChannel(name, int(c), float(values[0, c])) for c in np.flatnonzero(same)]
    return out


def join_streams(streams: SceneStreams, positions: np.ndarray) -> GaussianScene:
    """The GaussianScene of decoded ``streams`` at ``positions`` (N, 3) float32.

    SH bands without a stream decode as zeros up to ``sh_degree_stored``.
    """
    n = streams.count
    s = streams.float_streams
    bands = SH_REST_COUNTS[streams.sh_degree_stored]
    sh_rest = np.zeros((n, bands, 3), np.float32)
    for band in range(1, streams.sh_degree_stored + 1):
        if f"rest{band}" in s:
            lo, hi = SH_REST_COUNTS[band - 1], SH_REST_COUNTS[band]
            sh_rest[:, lo:hi, :] = s[f"rest{band}"].reshape(n, hi - lo, 3)
    return GaussianScene(
        positions=positions.astype(np.float32),
        sh_dc=s["dc"].astype(np.float32),
        sh_rest=sh_rest,
        opacity=s["opacity"].reshape(n).astype(np.float32),
        scales=s["scale"].astype(np.float32),
        rotations=smallest_three_to_quaternion(streams.rot_axis, s["rot"]),
    )
