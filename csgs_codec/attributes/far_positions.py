"""Far points coded apart from the position grid with relative precision (FORMAT §12.20).

A far point p (outside the grid) is coded as its offset v = p - c from a centre c (the grid's
centre, float64), with one exponent e per point and one integer mantissa per axis:

    v_a ~= m_a * 2^(e - b),   m_a in [-2^b, 2^b - 1],   e in [E_MIN, E_MAX]

``b`` (mantissa bits, 1..MAX_MANTISSA_BITS) is fixed per file. The decoder computes
``float32(c_a + float64(m_a) * 2^(e - b))``: the product is exact (a power-of-two scaling of
an integer below 2^31, far from float64's range limits) and the sum and the cast are each
one correctly rounded IEEE operation, so every machine decodes the same bits.

Error bound, per axis, with r = max_a |v_a| (the Chebyshev distance from the centre):

    |decoded_a - p_a| <= 2^(1 - b) * r + ulp32(decoded_a)

(2^(e - b - 1) <= 2^(1 - b) r for the exponent the encoder picks, plus the float64 and
float32 roundings). Seen from the centre this is a fixed angular precision: a far point at
1e4 needs no finer absolute precision than the grid gives at the core's edge. Points the
scheme cannot represent (r >= 2^E_MAX, or a decoded value beyond float32) are left to the
exact float32 list (OUTL).
"""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import InputError

#: Exponent range of a far point (stored as a byte, e = byte - 128).
E_MIN, E_MAX = -128, 127
#: Largest mantissa bits per axis (the mantissa then fits 31 bits with its sign).
MAX_MANTISSA_BITS = 30


def error_bound(offsets: np.ndarray, decoded: np.ndarray, mantissa_bits: int) -> np.ndarray:
    """The documented per-axis error bound (N, 3) float64, world units, of far points with
    ``offsets`` (N, 3) from the centre and ``decoded`` (N, 3) float32 positions."""
    r = np.max(np.abs(np.asarray(offsets, np.float64)), axis=1, keepdims=True)
    ulp = np.spacing(np.abs(np.asarray(decoded, np.float32))).astype(np.float64)
    return np.ldexp(r, 1 - mantissa_bits) + ulp


def quantize_far(positions: np.ndarray, centre, mantissa_bits: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Code far points relative to ``centre``.

    Args:
        positions: (N, 3) finite world positions (float32 or float64).
        centre: (3,) float64 world units.
        mantissa_bits: b, 1..MAX_MANTISSA_BITS.

    Returns:
        exponents (N,) int64 in [E_MIN, E_MAX], mantissas (N, 3) int64 in [-2^b, 2^b - 1],
        and the (N,) boolean mask of points the scheme codes within its bound (the others
        must be kept exactly; their exponent and mantissas are 0).
    """
    if not 1 <= mantissa_bits <= MAX_MANTISSA_BITS:
        raise InputError(f"mantissa_bits must be in 1..{MAX_MANTISSA_BITS}",
                         property="mantissa_bits")
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    v = p - np.asarray(centre, np.float64)
    r = np.max(np.abs(v), axis=1)
    _, e = np.frexp(r)  # r = f * 2^e, f in [0.5, 1): |v_a| < 2^e
    e = e.astype(np.int64)
    e[r == 0] = E_MIN
    top = 1 << mantissa_bits
    with np.errstate(over="ignore", invalid="ignore"):
        m = np.rint(np.ldexp(v, (mantissa_bits - e)[:, None]))
        bump = np.any(m > top - 1, axis=1)  # v_a rounds up to 2^b: one exponent more
        e[bump] += 1
        m[bump] = np.rint(np.ldexp(v[bump], (mantissa_bits - e[bump])[:, None]))
    ok = (e >= E_MIN) & (e <= E_MAX) & np.all((m >= -top) & (m <= top - 1), axis=1)
    e[~ok], m[~ok] = 0, 0
    m = m.astype(np.int64)
    decoded = dequantize_far(centre, mantissa_bits, e, m)
    with np.errstate(invalid="ignore"):
        finite = np.all(np.isfinite(decoded), axis=1)
        err = np.abs(decoded.astype(np.float64) - p)
        bound = error_bound(v, np.where(finite[:, None], decoded, 0), mantissa_bits)
        ok &= finite & np.all(err <= bound, axis=1)
    e[~ok], m[~ok] = 0, 0
    return e, m, ok


def dequantize_far(centre, mantissa_bits: int, exponents: np.ndarray,
                   mantissas: np.ndarray) -> np.ndarray:
    """Decoded far positions (N, 3) float32: ``float32(c_a + m_a * 2^(e - b))``; may hold
    inf where the value overflows float32 (callers check)."""
    e = np.asarray(exponents, np.int64).reshape(-1)
    m = np.asarray(mantissas, np.int64).reshape(-1, 3).astype(np.float64)
    with np.errstate(over="ignore"):
        offsets = np.ldexp(m, (e - mantissa_bits)[:, None])
        return (np.asarray(centre, np.float64) + offsets).astype(np.float32)
