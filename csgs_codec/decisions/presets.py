"""Quality presets: quantization steps per attribute type and position resolution.

Steps are in each attribute's coding form: SH coefficients (color = 0.5 + 0.2821 * dc, so a
dc step of 0.01 is about 0.7/255 of color), opacity logits, natural-log scales, the
smallest-three rotation components scaled to [-1, 1], and semantic features in the trainer's
units (click selection on unit-scale features is unchanged down to a step of 1/8, measured by
benchmarks/selection.py, so quality 1 uses 1/8 and quality 9 1/240). Position bits are per
axis over the scene's robust extent. Quality 1 is the smallest file; 10-12 are the
near-lossless end for archives (standard scenes only; anchor scenes and training take 1..9).

Calibration (samples/donut.ply, 4 orbit views at 400x300, foreground PSNR of the decoded
against the original render): about 26 dB at 1, 31 at 2, 40 at 4, 47 at 6, 53 at 8. On the
full-precision SH-3 scenes (../shared/data/real_sh3, 28 held-out views at 400x300):
fruit_drops 51.4 dB at 9, 60.2 at 10, 66.7 at 11; leica_sofort_top8192 48.7, 57.2, 65.1 dB
(quality 12, with the step allocation, on 28 held-out views at 800x600: 74.4 and 71.2 dB).

The encoder's step allocation (:mod:`csgs_codec.decisions.step_allocation`, on by default for
scenes with SH bands) moves a scene's steps and grid bits from its preset's: the bounds below
then hold for the settings it used (``EncodeReport.allocation.apply(preset)``; the file
records each stream's step and the grid's bits), and for the preset itself with
``step_allocation=False`` (``--no-step-allocation``).

Position error bound guaranteed by a preset of ``position_bits`` = B, per axis, for every
Gaussian (FORMAT §12.5, §12.20), with E the largest side of the dense core's 1-99 percentile
box (csgs_codec/attributes/position_grid.py; far floaters of any share below one half leave it
unchanged) and ulp32(x) the float32 spacing at the decoded coordinate:

- a Gaussian on the position grid (every Gaussian within about 2^(20 - B) E of the core's centre,
  or all of them when the scene fits 21 bits): error <= cell / 2 + ulp32(x), with
  cell = E / (2^B - 1) (:attr:`PositionGrid.max_error`);
- a far point coded apart with relative precision (OUTQ): error <= 2^-B r + ulp32(x), with r
  its Chebyshev distance from the core's centre: the angular precision of a cell at the
  core's edge (csgs_codec/attributes/far_positions.py);
- a far point kept exactly (OUTL: at most 16 far points in a scene, or one the relative code
  cannot represent): no error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError

#: Steps at multiplier 1 (quality 8), in coding-form units.
_BASE = {"dc": 0.025, "rest": 0.05, "opacity": 0.12, "scale": 0.05, "rotation": 0.025,
         "semantic": 1.0 / 96}


@dataclass(frozen=True)
class Preset:
    """Quantization settings of one quality level (units: see the module docstring)."""

    quality: int
    position_bits: int
    dc_step: float
    rest_step: float
    opacity_step: float
    scale_step: float
    rotation_step: float
    semantic_step: float
    #: Each SH band's step over ``rest_step`` (bands 1, 2, 3): 1 in every preset; the
    #: encoder's step allocation moves them per scene (:mod:`csgs_codec.decisions.step_allocation`).
    rest_band_factors: tuple[float, float, float] = (1.0, 1.0, 1.0)


def _row(quality: int, bits: int, multiplier: float) -> Preset:
    return Preset(quality, bits, *(v * multiplier for v in _BASE.values()))


#: Step multiplier of each preset (their steps are ``_BASE`` times it).
MULTIPLIERS = {1: 12.0, 2: 8.0, 3: 6.0, 4: 4.0, 5: 3.0, 6: 2.0, 7: 1.4, 8: 1.0, 9: 0.4,
               10: 0.15, 11: 0.06, 12: 0.03}
#: Every quality of a standard scene, and those of anchor scenes and training (FORMAT §17's
#: header field is 1..9): the near-lossless end is for standard scenes.
QUALITIES = tuple(MULTIPLIERS)
ANCHOR_QUALITIES = tuple(range(1, 10))

# 10-12 follow the ladder's trend (:func:`scaled_preset`): on leica_sofort_top8192, 18
# bits instead of 16 at 10 measured +0.2 dB for 1.7% more bytes. 12 is the archival end: it
# reaches Draco's 12-bit points (61-71 dB foreground PSNR on the SH-3 captures), which 11 does
# not on fruit_drops and leica_sofort_top8192.
_BITS = {1: 10, 2: 11, 3: 11, 4: 12, 5: 12, 6: 13, 7: 14, 8: 14, 9: 16, 10: 18, 11: 19, 12: 20}
PRESETS = {q: _row(q, _BITS[q], MULTIPLIERS[q]) for q in MULTIPLIERS}
DEFAULT_QUALITY = 5
#: How rotation steps follow decoded attributes (``Encoder(rotation_steps=...)``,
#: ``csgs encode --rotation-steps``): footprint is the float stream's scored steps, uniform
#: one step for all.
ROTATION_STEPS = ("footprint", "uniform")
DEFAULT_ROTATION_STEPS = "footprint"

#: Anchor scenes (spec §17) use the same multipliers on their own steps at quality 8, in
#: coding units: features, offsets (units of exp(scaling[:3])), natural-log scaling, semantic
#: features. Semantic features are compared by cosine similarity, so a step of 1/64 (3/64 at
#: the default quality, errors <= 0.024 per channel of a unit-scale feature) keeps
#: selections intact at a few bits per channel.
ANCHOR_BASE_STEPS = {"f": 0.02, "offsets": 0.01, "scaling": 0.005, "semantic": 1.0 / 64}


def preset_steps(preset: Preset) -> dict[str, float]:
    """Step of each float stream under ``preset`` (coding-form units)."""
    rest = [preset.rest_step * f for f in preset.rest_band_factors]
    return {"dc": preset.dc_step, "rest1": rest[0], "rest2": rest[1], "rest3": rest[2],
            "opacity": preset.opacity_step, "scale": preset.scale_step,
            "rot": preset.rotation_step}


def preset(quality: int) -> Preset:
    """The preset for ``quality`` in 1..12.

    Raises:
        InputError: quality out of range.
    """
    if quality not in PRESETS:
        raise InputError(f"quality must be 1..{QUALITIES[-1]}, got {quality}",
                         property="quality")
    return PRESETS[quality]


def scaled_preset(multiplier: float) -> Preset:
    """Settings between the presets: every step ``multiplier`` times its base (0.03..64) and
    grid bits following the presets' trend (about 1.2 bits per axis per halving of the
    steps). Its ``quality`` is the preset with the nearest multiplier (informative only)."""
    if not 0.03 <= multiplier <= 64.0:
        raise InputError(f"step multiplier must be in [0.03, 64], got {multiplier}")
    bits = int(np.clip(np.rint(14.3 - 1.2 * np.log2(multiplier)), 8, 21))
    nearest = min(MULTIPLIERS, key=lambda q: abs(np.log(MULTIPLIERS[q] / multiplier)))
    return _row(nearest, bits, multiplier)
