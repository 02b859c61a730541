"""Quality presets: quantization steps per attribute type and position resolution.

Steps are in each attribute's coding form: SH coefficients (colour = 0.5 + 0.2821 * dc, so a
dc step of 0.01 is about 0.7/255 of colour), opacity logits, natural-log scales, and the
smallest-three rotation components scaled to [-1, 1]. Quality 1 is the smallest file, 9 is
near-lossless. ``lambda_`` weights distortion against rate in the hyperprior's fit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from csgs_codec.errors import InputError


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
    lambda_: float

    def with_lambda(self, lambda_: float) -> Preset:
        """The same preset with another rate-distortion weight."""
        if not lambda_ > 0:
            raise InputError(f"lambda must be positive, got {lambda_}")
        return replace(self, lambda_=float(lambda_))


_TABLE = [
    # q  bits  dc      rest    opac   scale   rot     lambda
    (1, 12, 0.100, 0.200, 0.50, 0.200, 0.100, 0.5),
    (2, 13, 0.070, 0.140, 0.35, 0.140, 0.070, 1.0),
    (3, 14, 0.050, 0.100, 0.25, 0.100, 0.050, 2.0),
    (4, 14, 0.035, 0.070, 0.18, 0.070, 0.035, 4.0),
    (5, 15, 0.025, 0.050, 0.12, 0.050, 0.025, 8.0),
    (6, 16, 0.016, 0.032, 0.08, 0.032, 0.016, 16.0),
    (7, 16, 0.010, 0.020, 0.05, 0.020, 0.010, 32.0),
    (8, 17, 0.005, 0.010, 0.025, 0.010, 0.005, 64.0),
    (9, 18, 0.002, 0.004, 0.010, 0.004, 0.002, 128.0),
]
PRESETS = {row[0]: Preset(*row) for row in _TABLE}
DEFAULT_QUALITY = 6


def preset(quality: int) -> Preset:
    """The preset for ``quality`` in 1..9.

    Raises:
        InputError: quality out of range.
    """
    if quality not in PRESETS:
        raise InputError(f"quality must be 1..9, got {quality}")
    return PRESETS[quality]
