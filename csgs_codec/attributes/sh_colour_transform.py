"""The SH bands' colour transform (FORMAT §12.24): the encoder's choice and the exact inverse
every decoder applies (the ``SHXF`` record that marks the bands is
:mod:`csgs_codec.chunks.sh_colour_transform`'s).

A band's three colour values of one coefficient (r, g, b) are strongly correlated, and
coding them apart lets small, correlated values all quantize to zero. The opponent
transform codes instead

    y0 = (r + g + b) / sqrt 3,   y1 = (r - b) / sqrt 2,   y2 = (r - 2g + b) / sqrt 6,

an orthonormal rotation (the squared error of a uniform quantizer is kept), at the same step.
Measured by benchmarks/sh_colour_transform.py: 4-19% fewer SH bytes and 0.3-1.4 dB better
held-out renders on fruit_drops, leica and playbot at qualities 5 and 7. The encoder
transforms a band when that plans smaller (:func:`choose_transforms`); DC gains nothing.

The decoder's inverse is specified to the bit: float32 inputs, binary64 products with the
constants below (exact binary64 values) and sums in a fixed order, each rounded once, and
one rounding to float32 at the end; numpy and JavaScript give the same values on every
machine.
"""

from __future__ import annotations

import numpy as np

from csgs_codec.attributes.float_stream import plan_float_stream
from csgs_codec.errors import FormatError

#: Transform ids (the ``SHXF`` record's values): a band coded as colours, or in opponent
#: colours.
IDENTITY = 0
OPPONENT = 1

#: The inverse's binary64 constants (FORMAT §12.24): about 1/sqrt 3, 1/sqrt 2, 1/sqrt 6 and
#: twice the last (exact).
INVERSE_A = float.fromhex("0x1.279a74590331dp-1")
INVERSE_B = float.fromhex("0x1.6a09e667f3bccp-1")
INVERSE_C = float.fromhex("0x1.a20bd700c2c3fp-2")
INVERSE_D = float.fromhex("0x1.a20bd700c2c3fp-1")


def forward(values: np.ndarray) -> np.ndarray:
    """(N, 3K) float32 band values, colours innermost -> the opponent values (encoder only;
    any accurate arithmetic will do, the decoder's inverse is what is specified)."""
    v = np.asarray(values, np.float64).reshape(len(values), -1, 3)
    r, g, b = v[..., 0], v[..., 1], v[..., 2]
    out = np.stack([(r + g + b) / np.sqrt(3.0), (r - b) / np.sqrt(2.0),
                    (r - 2.0 * g + b) / np.sqrt(6.0)], axis=-1)
    return out.reshape(len(values), -1).astype(np.float32)


#: Rows turned per block by :func:`inverse` (keeps its binary64 temporaries in cache).
_BLOCK_ROWS = 1 << 15


def inverse(values: np.ndarray) -> np.ndarray:
    """(N, 3K) float32 opponent values -> (r, g, b) float32, exactly as FORMAT §12.24 says:
    r = (A y0 + B y1) + C y2, g = A y0 - D y2, b = (A y0 - B y1) + C y2 in binary64.

    D y2 is taken as 2 (C y2): D = 2 C exactly and doubling a binary64 product is exact, so
    both are the same value (no product here can reach the subnormal range).
    """
    values = np.ascontiguousarray(values, np.float32)
    out = np.empty_like(values)
    for start in range(0, len(values), _BLOCK_ROWS):
        block = values[start:start + _BLOCK_ROWS]
        a0 = block[:, 0::3].astype(np.float64)
        b1 = block[:, 1::3].astype(np.float64)
        c2 = block[:, 2::3].astype(np.float64)
        a0 *= INVERSE_A
        b1 *= INVERSE_B
        c2 *= INVERSE_C
        rows = out[start:start + _BLOCK_ROWS]
        rows[:, 0::3] = (a0 + b1) + c2
        rows[:, 2::3] = (a0 - b1) + c2
        c2 *= 2.0
        rows[:, 1::3] = a0 - c2
    return out


def band_colours(values: np.ndarray, band: int, transforms: tuple[int, ...],
                 offset: int | None = None) -> np.ndarray:
    """Band ``band``'s decoded (N, 3K) values as colours: turned back when ``transforms``
    (one id per band, from SHXF) marks it opponent, else as they are.

    Raises:
        FormatError: a colour value overflows float32 (chunk SHXF, at ``offset``).
    """
    if band > len(transforms) or transforms[band - 1] != OPPONENT:
        return values
    with np.errstate(over="ignore", invalid="ignore"):
        colours = inverse(values)
    if not np.all(np.isfinite(colours)):
        raise FormatError(f"SH band {band}'s colours overflow float32", chunk="SHXF",
                          offset=offset)
    return colours


def apply_inverse(decoded: dict[str, np.ndarray], transforms: tuple[int, ...],
                  offset: int | None = None) -> None:
    """Replace each transformed band ``rest1..`` of ``decoded`` by its colours, in place
    (:func:`band_colours`)."""
    for band in range(1, len(transforms) + 1):
        decoded[f"rest{band}"] = band_colours(decoded[f"rest{band}"], band, transforms,
                                              offset)


def choose_transforms(plans: dict, values: dict[str, np.ndarray], steps: dict[str, float]
                      ) -> tuple[tuple[int, ...], dict]:
    """The encoder's choice per band: the opponent transform where its plan codes smaller.

    Args:
        plans: stream name -> the :class:`csgs_codec.attributes.float_stream.StreamPlan` of the
            bands as colours (``rest1``.. present for the coded bands).
        values: stream name -> (N, C) coding-form values (the bands as colours).
        steps: stream name -> quantization step (each band's, ``rest1``..).

    Returns:
        (transform id per band, name -> the plan of each band in opponent colours where it
        was chosen).
    """
    transforms, chosen = [], {}
    band = 1
    while f"rest{band}" in plans:
        name = f"rest{band}"
        turned = plan_float_stream(forward(values[name]), steps[name])
        better = _bits(turned) < _bits(plans[name])
        transforms.append(OPPONENT if better else IDENTITY)
        if better:
            chosen[name] = turned
        band += 1
    return tuple(transforms), chosen


def _bits(plan) -> float:
    return float(sum(channel.cost for channel in plan.channels))
