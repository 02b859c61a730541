"""The color codec's documented error bounds, as checks on a decoded scene.

Bounds (spec/FORMAT.md §12.4, §12.8, §16.3.1; csgs_codec/decisions/presets.py), for the steps an
encode used (the preset's; a rate-controlled encoder's plan where its report has one):

- a coded value is ``mu + q k`` with k the round-half-up of (a - mu) / q on the value grid of F
  fractional bits, so it errs by at most q / 2, plus half a grid unit (2^-F-1) for placing the
  input on the grid, plus half a float32 ulp of the output; q is the step snapped to the
  integer step table (:func:`snapped_step`: within sqrt(9/8) of the step asked for, or one
  grid unit when the step is finer than the grid);
- constant channels are exact; semantic features have the fixed step 1/256, labels are exact;
- opacity logits are compared with the input clamped to +-10 (the encoder's clamp, §12.13);
- grid positions err by at most ``PositionGrid.max_error`` per axis; far outliers are exact;
- rotations are compared as unit quaternions up to sign, zero quaternions as the identity;
  each of the three stored components errs by at most e = q / 2 / sqrt(2) and the dropped
  (largest, >= 1/2) one by what those errors can move sqrt(1 - sum of their squares), from
  about e^2 near the identity to about 3e near (1/2, 1/2, 1/2, 1/2)
  (:func:`dropped_component_bound`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from csgs_codec.attributes import sh_colour_transform as xf
from csgs_codec.attributes.attribute_forms import (
    OPACITY_LOGIT_LIMIT,
    canonical_orientations,
    canonical_rotations,
    normalize_quaternions,
    quaternion_to_smallest_three,
)
from csgs_codec.attributes.float_stream import MAX_FRAC_BITS, frac_bits_for
from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.codec.encoder import EncodeReport
from csgs_codec.decisions.presets import Preset
from csgs_codec.decisions.presets import preset_steps as stream_steps
from csgs_codec.entropy.residual import STEP_COUNT, step_index, step_size
from csgs_codec.format import read_layers
from csgs_codec.scene.gaussian_scene import GaussianScene


def snapped_step(step: float, frac_bits: int) -> float:
    """The step (value units) the coder uses when asked for ``step`` on a value grid of
    ``frac_bits`` fractional bits: the nearest step of the integer step table (§16.3.1)."""
    index = step_index(np.array([step * 2.0**frac_bits]))
    return float(step_size(index)[0]) * 2.0**-frac_bits


def value_bound(reference: np.ndarray, step: float) -> np.ndarray:
    """Largest allowed |decoded - reference| per element of one float stream (same shape).

    ``reference`` is the whole (N, C) stream: its largest magnitude fixes the value grid.
    """
    ref = np.asarray(reference, np.float32)
    f = frac_bits_for(ref.reshape(len(ref), -1)) if ref.size else 0
    grid_unit = 2.0 ** -f
    half_step = snapped_step(step, f) / 2
    ulp = np.spacing(np.abs(ref)).astype(np.float64)
    return half_step + grid_unit / 2 + ulp


def assert_values_within(name: str, decoded: np.ndarray, reference: np.ndarray,
                         step: float) -> None:
    """Assert |decoded - reference| stays within :func:`value_bound`, naming the worst value."""
    error = np.abs(decoded.astype(np.float64) - reference.astype(np.float64))
    bound = value_bound(reference, step)
    excess = error - bound
    assert not excess.size or excess.max() <= 0, (
        f"{name}: error {error.reshape(-1)[np.argmax(excess)]:.6g} exceeds its bound "
        f"{bound.reshape(-1)[np.argmax(excess)]:.6g} at value "
        f"{reference.reshape(-1)[np.argmax(excess)]:.6g}")


def assert_positions_within(decoded: GaussianScene, reference: GaussianScene,
                            position_bits: int) -> None:
    """Grid points within the grid's max error per axis, far outliers exact."""
    grid = PositionGrid.fit(reference.positions, position_bits)
    _, inside = grid.quantize(reference.positions)
    error = np.abs(decoded.positions.astype(np.float64) - reference.positions.astype(np.float64))
    assert np.all(decoded.positions[~inside] == reference.positions[~inside]), "far outliers"
    if inside.any():
        assert error[inside].max() <= grid.max_error, (
            f"positions: error {error[inside].max():.6g} exceeds {grid.max_error:.6g}")


def rotation_component_error(step: float, class_offset: int = 0) -> float:
    """Largest error of one stored smallest-three component (quaternion units, on the
    finest value grid, which rotations in [-1, 1] always get); ``class_offset`` is how many
    entries of the step table above ``step``'s a Gaussian's own step may lie (classed
    steps, FORMAT §12.8: the table's integer steps are not exactly geometric, so the bound
    takes the entry itself, not the step times 2^(offset/8))."""
    index = step_index(np.array([step * 2.0**MAX_FRAC_BITS]))
    coarse = float(step_size(np.minimum(index + class_offset, STEP_COUNT - 1))[0])
    return coarse * 2.0**-MAX_FRAC_BITS / 2 / np.sqrt(2.0) + 1e-6


def dropped_component_bound(reference: np.ndarray, e: float) -> np.ndarray:
    """(N,) largest error of the dropped (largest) component of each unit quaternion of
    ``reference`` (N, 4) when each stored one errs by at most ``e``.

    The decoder takes sqrt(max(0, 1 - sum of the stored squares)): with each stored
    magnitude within [|c| - e, |c| + e], the sum lies in an interval and so does the decoded
    component. Near (1/2, 1/2, 1/2, 1/2) that interval is widest (about 3e); near the identity
    it is about e^2.
    """
    q = np.abs(reference.astype(np.float64))
    dropped = np.argmax(q, axis=1)
    rows = np.arange(len(q))
    big = q[rows, dropped]
    keep = np.ones_like(q, dtype=bool)
    keep[rows, dropped] = False
    stored = q[keep].reshape(-1, 3)
    low = np.sum(np.maximum(stored - e, 0.0) ** 2, axis=1)
    high = np.sum((stored + e) ** 2, axis=1)
    largest = np.sqrt(np.maximum(1.0 - low, 0.0))
    smallest = np.sqrt(np.maximum(1.0 - high, 0.0))
    return np.maximum(largest - big, big - smallest) + 1e-5


def assert_rotations_within(decoded: np.ndarray, reference: np.ndarray, step: float,
                            class_offset: int = 0) -> None:
    """Unit quaternions up to sign: within the bound of the module notes per component."""
    ref = normalize_quaternions(reference).astype(np.float64)
    dec = decoded.astype(np.float64)
    sign = np.where(np.sum(ref * dec, axis=1) < 0, -1.0, 1.0)
    error = np.abs(dec - sign[:, None] * ref)
    e = rotation_component_error(step, class_offset)
    dropped, _ = quaternion_to_smallest_three(reference)
    rows = np.arange(len(ref))
    stored = np.ones_like(error, dtype=bool)
    stored[rows, dropped] = False
    if len(ref):
        assert error[stored].max() <= e, f"rotation component error {error[stored].max():.4g}"
        big = dropped_component_bound(ref, e)
        worst = int(np.argmax(error[rows, dropped] - big))
        assert error[worst, dropped[worst]] <= big[worst], (
            f"largest rotation component error {error[worst, dropped[worst]]:.4g} > "
            f"{big[worst]:.4g} (Gaussian {worst}, reference {ref[worst]})")


@dataclass(frozen=True)
class CodingSteps:
    """The steps an encode used: stream name -> step (coding-form units), and grid bits.

    Stream names: "dc", "rest1".."rest3", "opacity", "scale", "rot"
    (csgs_codec/attributes/streams.py) and "semantic".
    """

    steps: dict[str, float]
    position_bits: int
    #: SH bands (1..3) some tile codes in opponent colours (SHXF, FORMAT §12.24).
    opponent_bands: frozenset[int] = frozenset()
    #: How many step-table entries above ``steps["rot"]``'s a Gaussian's rotation step may
    #: lie: 0 for one step, 12 when rotations are coded with scored steps (the encoder
    #: clips each class to +-12 entries, eighth octaves, of the channel's step).
    rotation_class_offset: int = 0


def preset_steps(preset: Preset) -> CodingSteps:
    """The steps of a quality preset (what a fixed-step encode uses; each SH band's own,
    :attr:`Preset.rest_band_factors` included)."""
    return CodingSteps({**stream_steps(preset), "semantic": preset.semantic_step},
                       preset.position_bits)


def result_steps(result: EncodeReport, preset: Preset) -> CodingSteps:
    """The steps an encode used: a rate-controlled encoder's plan where its report carries one
    (``result.plan`` with ``steps`` and ``position_bits``), else the preset's as the step
    allocation moved them (``result.allocation``, default on for scenes with SH bands)."""
    if result.allocation is not None:
        preset = result.allocation.apply(preset)
    steps = preset_steps(preset)
    opponent = opponent_bands(result.data)
    offset = rotation_class_offset(result.data)
    plan = getattr(result, "plan", None)
    if plan is None:
        return replace(steps, opponent_bands=opponent, rotation_class_offset=offset)
    return CodingSteps({**steps.steps, **plan.steps}, plan.position_bits, opponent, offset)


def rotation_class_offset(data: bytes) -> int:
    """:attr:`CodingSteps.rotation_class_offset` of the file ``data``: the classes' clip
    when any tile's ROTN codes a channel with classed steps, else 0."""
    from csgs_codec.attributes.derived_steps import FOOTPRINT_CLIP
    from csgs_codec.chunks.color_streams import rotation_class_table
    from csgs_codec.format.primitives import ByteReader

    container = read_layers(data, layers={"color"})
    for entry in container.toc:
        if entry.type == "ROTN":
            reader = ByteReader(bytes(container.payloads[entry.index]), chunk="ROTN")
            if rotation_class_table(reader).scored:
                return FOOTPRINT_CLIP
    return 0


def opponent_bands(data: bytes) -> frozenset[int]:
    """The SH bands any tile of ``data`` codes in opponent colours (its SHXF records)."""
    container = read_layers(data, layers={"color"})
    bands = set()
    for entry in container.toc:
        if entry.type == "SHXF":
            record = bytes(container.payloads[entry.index])
            bands |= {b for b, t in enumerate(record[2:], start=1) if t == xf.OPPONENT}
    return frozenset(bands)


def assert_opponent_band_within(name: str, decoded: np.ndarray, reference: np.ndarray,
                                step: float) -> None:
    """A band coded in opponent colours: each opponent value is within its own bound, and a
    colour mixes three of them (weights A, B, C of the inverse), plus float32 roundings."""
    turned = xf.forward(reference)
    per_value = value_bound(turned, step).reshape(len(turned), -1, 3).max(axis=2)
    mix = xf.INVERSE_A + xf.INVERSE_B + xf.INVERSE_C
    bound = (np.repeat(per_value, 3, axis=1) * mix
             + 4 * np.spacing(np.abs(reference)).astype(np.float64)
             + 4 * np.spacing(np.repeat(np.abs(turned).reshape(len(turned), -1, 3)
                                        .max(axis=2), 3, axis=1)).astype(np.float64))
    error = np.abs(decoded.astype(np.float64) - reference.astype(np.float64))
    excess = error - bound
    assert not excess.size or excess.max() <= 0, (
        f"{name} (opponent colours): error {error.reshape(-1)[np.argmax(excess)]:.6g} "
        f"exceeds its bound {bound.reshape(-1)[np.argmax(excess)]:.6g}")


def assert_within_bounds(decoded: GaussianScene, reference: GaussianScene,
                         coding: CodingSteps, *, sorted_axes: bool) -> None:
    """Every decoded attribute within the bounds of ``coding``'s steps of ``reference``.

    Both scenes are in the decoder's order. Scales and rotations are compared in the form the
    encoder codes (the same Gaussians): rotations as :func:`canonical_rotations` gives them,
    and, where the encoder sorted the axes (``sorted_axes``, the report's), axes in the order
    of :func:`canonical_orientations`.
    """
    assert len(decoded) == len(reference)
    assert decoded.sh_rest.shape == reference.sh_rest.shape
    n = len(reference)
    if n == 0:
        return
    step = coding.steps
    assert_positions_within(decoded, reference, coding.position_bits)
    assert_values_within("sh_dc", decoded.sh_dc, reference.sh_dc, step["dc"])
    for band, (lo, hi) in enumerate(((0, 3), (3, 8), (8, 15)), start=1):
        if reference.sh_rest.shape[1] >= hi:
            ref_band = reference.sh_rest[:, lo:hi].reshape(n, -1)
            check = (assert_opponent_band_within if band in coding.opponent_bands
                     else assert_values_within)
            check(f"sh band {band}", decoded.sh_rest[:, lo:hi].reshape(n, -1), ref_band,
                  step[f"rest{band}"])
    clamped = np.clip(reference.opacity, -OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT)
    assert_values_within("opacity", decoded.opacity, clamped, step["opacity"])
    rotations, scales = coded_orientations(reference, sorted_axes)
    assert_values_within("scales", decoded.scales, scales, step["scale"])
    assert_rotations_within(decoded.rotations, rotations, step["rot"],
                            coding.rotation_class_offset)
    assert (decoded.semantic is None) == (reference.semantic is None)
    if reference.semantic is not None:
        assert decoded.semantic_names == reference.semantic_names
        assert_values_within("semantic", decoded.semantic, reference.semantic,
                             step["semantic"])
    if reference.labels is not None:
        assert np.array_equal(decoded.labels, reference.labels), "labels"


def coded_orientations(scene: GaussianScene, sorted_axes: bool
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(rotations (N, 4), log-scales (N, 3)) of ``scene`` in the form the encoder codes them
    (``sorted_axes``: the report's decision)."""
    if sorted_axes:
        return canonical_orientations(scene.rotations, scene.scales)
    return canonical_rotations(scene.rotations), scene.scales.astype(np.float32)


def assert_all_finite(scene: GaussianScene) -> None:
    """No NaN or Inf in any float attribute of ``scene``."""
    for name, values in scene.attributes().items():
        assert np.all(np.isfinite(values)), f"non-finite value in decoded {name}"
