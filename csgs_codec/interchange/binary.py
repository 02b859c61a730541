"""Shared helpers of the interchange readers: bounds-checked byte access and the activations
between the stored forms (8-bit color, linear scale, alpha) and the INRIA raw values."""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import InputError

#: Degree-0 real spherical harmonic, Y_00 = 1 / (2 sqrt(pi)): color = 0.5 + SH_C0 * f_dc.
SH_C0 = 0.28209479177387814
#: Alpha is clamped to [ALPHA_EPS, 1 - ALPHA_EPS] before the logit, so 0 and 1 stay finite
#: (logit +-13.8), as splat-transform does.
ALPHA_EPS = 1e-6
#: Linear scales at or below this read as this (log -27.6): a zero-thickness Gaussian.
MIN_LINEAR_SCALE = 1e-12
#: SH coefficient count per color channel for SH degree 0..3.
SH_COEFFS = (0, 3, 8, 15)


class Bytes:
    """A file's bytes with reads that fail as :class:`InputError` naming file and offset.

    Args:
        data: the whole file.
        source: its name, for messages.
    """

    def __init__(self, data: bytes, source: str) -> None:
        self.data = data
        self.source = source

    def __len__(self) -> int:
        return len(self.data)

    def error(self, message: str, offset: int | None = None, **where) -> InputError:
        """An :class:`InputError` about this file at ``offset``."""
        return InputError(message, file=self.source, offset=offset, **where)

    def need(self, offset: int, size: int, what: str) -> None:
        """Raise unless ``size`` bytes of ``what`` fit at ``offset``."""
        if offset < 0 or size < 0 or offset + size > len(self.data):
            raise self.error(f"{what} needs {size} bytes at byte {offset} but the file has "
                             f"{len(self.data)} (truncated file or a count larger than the "
                             "file)", offset=min(max(offset, 0), len(self.data)))

    def array(self, offset: int, dtype, count: int, what: str) -> np.ndarray:
        """``count`` items of little-endian ``dtype`` at ``offset`` (a read-only view)."""
        dtype = np.dtype(dtype).newbyteorder("<")
        self.need(offset, count * dtype.itemsize, what)
        return np.frombuffer(self.data, dtype=dtype, count=count, offset=offset)


def color_to_dc(values: np.ndarray) -> np.ndarray:
    """8-bit or [0, 1] color (already divided by 255) -> SH DC coefficient, float32."""
    return ((np.asarray(values, np.float64) - 0.5) / SH_C0).astype(np.float32)


def dc_to_color(dc: np.ndarray) -> np.ndarray:
    """SH DC coefficient -> color in [0, 1] before clamping, float64."""
    return 0.5 + SH_C0 * np.asarray(dc, np.float64)


def alpha_to_logit(alpha: np.ndarray) -> np.ndarray:
    """Alpha in [0, 1] -> opacity logit (clamped off 0 and 1), float32."""
    a = np.clip(np.asarray(alpha, np.float64), ALPHA_EPS, 1.0 - ALPHA_EPS)
    return np.log(a / (1.0 - a)).astype(np.float32)


def logit_to_alpha(logit: np.ndarray) -> np.ndarray:
    """Opacity logit -> alpha in (0, 1), float64."""
    return 1.0 / (1.0 + np.exp(-np.asarray(logit, np.float64)))


def linear_to_log_scale(scale: np.ndarray) -> np.ndarray:
    """Linear scale -> natural-log scale, float32 (zero and negative read as tiny)."""
    s = np.asarray(scale, np.float64)
    with np.errstate(invalid="ignore"):
        s = np.where(s > MIN_LINEAR_SCALE, s, MIN_LINEAR_SCALE)
    return np.log(s).astype(np.float32)


def to_uint8(values: np.ndarray) -> np.ndarray:
    """Round to nearest and clamp to 0..255, uint8."""
    return np.clip(np.rint(np.asarray(values, np.float64)), 0, 255).astype(np.uint8)


def normalized_wxyz(rotations: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions normalised, (1, 0, 0, 0) where the norm is zero, float64."""
    q = np.asarray(rotations, np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    out = np.zeros_like(q)
    out[:, 0] = 1.0
    good = norm[:, 0] > 0
    out[good] = q[good] / norm[good]
    return out


def from_smallest_three(largest: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(N, 4) float64 quaternions from "smallest three" storage: ``largest`` (N,) the slot
    0..3 of the component left out (rebuilt as sqrt(1 - sum of the others' squares)) and
    ``others`` (N, 3) the remaining components in slot order."""
    n = len(largest)
    out = np.zeros((n, 4))
    rows = np.arange(n)
    for slot in range(4):
        take = largest != slot
        # slot s receives the (s - [largest < s])-th of the three stored components
        index = slot - (largest < slot)
        out[take, slot] = others[rows[take], index[take]]
    out[rows, largest] = np.sqrt(np.maximum(0.0, 1.0 - np.sum(others * others, axis=1)))
    return out


def sh_rest_from_channel_major(values: np.ndarray, n: int, coeffs: int) -> np.ndarray:
    """(N, 3 * coeffs) channel-major SH (PLY ``f_rest_*`` order) -> (N, coeffs, 3) float32."""
    return np.ascontiguousarray(
        np.asarray(values, np.float32).reshape(n, 3, coeffs).transpose(0, 2, 1))


def round_half_away(values: np.ndarray) -> np.ndarray:
    """Round to the nearest integer, halves away from zero (C's ``round``), float64."""
    v = np.asarray(values, np.float64)
    return np.sign(v) * np.floor(np.abs(v) + 0.5)


def optional_module(name: str, what: str):
    """Import ``name`` or raise UnsupportedError saying that ``what`` needs the ``formats``
    extra (``pip install 'csgs[formats]'``)."""
    import importlib

    from csgs_codec.errors import UnsupportedError

    try:
        return importlib.import_module(name)
    except ImportError:
        raise UnsupportedError(f"{what} needs the Python package '{name}': install the "
                               "'formats' extra (pip install 'csgs[formats]')") from None
