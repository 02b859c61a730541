"""Frozen integer tables: the zero-mean Gaussian family v1 and the sine table v1.

Both are read from package data files written once by :mod:`csgs_codec.entropy.tablegen`,
checked against the SHA-256 in spec/FORMAT.md §16.2, and never recomputed from erf or sin.
A table with index s has half-width K_s and 2K_s+2 frequencies summing to 2^16: symbol i in
[0, 2K_s] stands for the residual i - K_s and symbol 2K_s+1 is the escape.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path

import numpy as np

from csgs_codec.entropy.coder_model import TOTAL, categorical_model
from csgs_codec.errors import FormatError

DATA_DIR = Path(__file__).resolve().parent / "data"

GAUSSIAN_V1_SHA256 = "be7447d49ca61827969ac45ce3fe504e5014afe6197cef91ff2c27303434d3ff"
SINE_V1_SHA256 = "a776046b72ec50a186312712e4065b05eaba980074502b920f3cee8a071f311a"

#: Scale grid of the Gaussian family v1 (encoder side only: maps a float sigma to an index).
SIGMA_MIN = 0.11
SIGMA_MAX = 128.0
SCALE_COUNT = 64
SINE_INDEX_BITS = 10
SINE_AMPLITUDE_BITS = 14


def _read_verified(name: str, sha256: str) -> bytes:
    data = (DATA_DIR / name).read_bytes()
    if hashlib.sha256(data).hexdigest() != sha256:
        raise FormatError(f"frozen table file {name} does not match its SHA-256 {sha256}",
                          file=DATA_DIR / name)
    return data


@dataclass(frozen=True)
class TableFamily:
    """A frozen family of zero-mean integer frequency tables.

    Attributes:
        half_widths: (S,) int64, K_s of each table.
        freqs: tuple of S read-only (2K_s+2,) int64 arrays, each summing to 2^16.
    """

    half_widths: np.ndarray
    freqs: tuple[np.ndarray, ...]

    @property
    def count(self) -> int:
        """Number of tables S."""
        return len(self.freqs)


@cache
def table_model(index: int):
    """The constriction ``Categorical`` of Gaussian table ``index`` (cached).

    The probabilities are the dyadic f / 2^16, exact in float64, so constriction's own
    quantization to its 24-bit precision is the same on every machine.
    """
    freqs = gaussian_family().freqs[index]
    return categorical_model(freqs)


def parse_gaussian_family(data: bytes) -> TableFamily:
    """Parse the frozen family bytes: u16 S, then per table u16 K and 2K+2 u16 frequencies."""
    view = np.frombuffer(data, dtype="<u2")
    count = int(view[0])
    pos = 1
    halves, freqs = [], []
    for _ in range(count):
        half = int(view[pos])
        table = view[pos + 1:pos + 1 + 2 * half + 2].astype(np.int64)
        table.setflags(write=False)
        if table.size != 2 * half + 2 or int(table.sum()) != TOTAL or table.min() < 1:
            raise FormatError("frozen Gaussian table family is malformed")
        halves.append(half)
        freqs.append(table)
        pos += 2 * half + 3
    if pos != view.size:
        raise FormatError("frozen Gaussian table family has trailing data")
    half_widths = np.asarray(halves, dtype=np.int64)
    half_widths.setflags(write=False)
    return TableFamily(half_widths, tuple(freqs))


@lru_cache(maxsize=1)
def gaussian_family() -> TableFamily:
    """The Gaussian family v1 (64 tables), loaded and SHA-256-checked on first use."""
    return parse_gaussian_family(_read_verified("gaussian_v1.bin", GAUSSIAN_V1_SHA256))


@lru_cache(maxsize=1)
def sine_table() -> np.ndarray:
    """(1024,) int64 read-only: round(2^14 * sin(2 pi i / 1024)), SHA-256-checked."""
    table = np.frombuffer(_read_verified("sine_v1.bin", SINE_V1_SHA256), dtype="<i2")
    table = table.astype(np.int64)
    table.setflags(write=False)
    return table


def scale_index(sigma: np.ndarray) -> np.ndarray:
    """Encoder helper: nearest table index (in log scale) for sigma in quantization steps.

    Args:
        sigma: (N,) float, the predicted standard deviation divided by the step q.

    Returns:
        (N,) int64 in [0, 63].
    """
    sigma = np.clip(np.asarray(sigma, dtype=np.float64), SIGMA_MIN, SIGMA_MAX)
    pos = np.log(sigma / SIGMA_MIN) / np.log(SIGMA_MAX / SIGMA_MIN) * (SCALE_COUNT - 1)
    return np.clip(np.rint(pos), 0, SCALE_COUNT - 1).astype(np.int64)
