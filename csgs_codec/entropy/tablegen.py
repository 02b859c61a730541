"""Generate the frozen integer tables once: ``python -m csgs_codec.entropy.tablegen``.

This is the only place floating-point ``erfc`` and ``sin`` are used. Its outputs are written
as little-endian integer files into ``csgs_codec/entropy/data/`` and are then frozen: decoders
load them and check their SHA-256 (spec/FORMAT.md §16.2.1, §16.2.2) and never recompute
them. Running the script again must reproduce the same bytes; ``--check`` verifies that
without writing.
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
from pathlib import Path

import numpy as np

DATA_DIR = Path(__file__).resolve().parent / "data"

#: Gaussian family v1: 64 scales log-spaced from 0.11 to 128 quantization steps.
SCALE_COUNT = 64
SIGMA_MIN = 0.11
SIGMA_MAX = 128.0
#: Half-width of a table: K = max(MIN_HALF_WIDTH, ceil(TAIL_SIGMAS * sigma)).
TAIL_SIGMAS = 5.0
MIN_HALF_WIDTH = 2
PRECISION = 16

#: Sine table v1: 2^SINE_INDEX_BITS entries of round(2^SINE_AMPLITUDE_BITS * sin(2 pi i / n)).
SINE_INDEX_BITS = 10
SINE_AMPLITUDE_BITS = 14


def sigma_grid() -> np.ndarray:
    """(SCALE_COUNT,) float64 scales in quantization steps: sigma_s = 0.11 * (128/0.11)^(s/63)."""
    s = np.arange(SCALE_COUNT, dtype=np.float64)
    return SIGMA_MIN * (SIGMA_MAX / SIGMA_MIN) ** (s / (SCALE_COUNT - 1))


def _normal_cdf(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def gaussian_frequencies(sigma: float) -> tuple[int, list[int]]:
    """Half-width K and the 2K+2 integer frequencies (sum 2^16) of one zero-mean table.

    Symbol i in [0, 2K] is the residual i - K; symbol 2K+1 is the escape. Each frequency is
    ``1 + floor(p * (2^16 - n))`` with p the Gaussian mass of the bin (or of both tails for
    the escape) and n = 2K+2; what is left of 2^16 goes to the residual 0.
    """
    half = max(MIN_HALF_WIDTH, math.ceil(TAIL_SIGMAS * sigma))
    n = 2 * half + 2
    total = 1 << PRECISION
    masses = [_normal_cdf((k + 0.5) / sigma) - _normal_cdf((k - 0.5) / sigma)
              for k in range(-half, half + 1)]
    masses.append(2.0 * _normal_cdf(-(half + 0.5) / sigma))
    freqs = [1 + math.floor(p * (total - n)) for p in masses]
    freqs[half] += total - sum(freqs)
    return half, freqs


def gaussian_table_bytes() -> bytes:
    """The frozen Gaussian family v1 as bytes: u16 count, then per table u16 K and u16 freqs."""
    out = bytearray(struct.pack("<H", SCALE_COUNT))
    for sigma in sigma_grid():
        half, freqs = gaussian_frequencies(float(sigma))
        out += struct.pack("<H", half)
        out += struct.pack(f"<{len(freqs)}H", *freqs)
    return bytes(out)


def sine_table_bytes() -> bytes:
    """The frozen sine table v1: 2^10 little-endian i16 values round(2^14 sin(2 pi i / 2^10))."""
    n = 1 << SINE_INDEX_BITS
    amp = 1 << SINE_AMPLITUDE_BITS
    values = [int(round(amp * math.sin(2.0 * math.pi * i / n))) for i in range(n)]
    # Exact quarter-wave symmetry, independent of libm rounding at 0, pi/2, pi, 3pi/2.
    quarter = n // 4
    for i in range(quarter + 1):
        values[n // 2 - i] = values[i]
    for i in range(n // 2):
        values[n // 2 + i] = -values[i]
    return np.asarray(values, dtype="<i2").tobytes()


FILES = {
    "gaussian_v1.bin": gaussian_table_bytes,
    "sine_v1.bin": sine_table_bytes,
}


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` verify) the frozen table files; prints their SHA-256."""
    import hashlib

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="verify, do not write")
    args = parser.parse_args(argv)
    status = 0
    for name, build in FILES.items():
        data = build()
        path = DATA_DIR / name
        digest = hashlib.sha256(data).hexdigest()
        if args.check:
            same = path.exists() and path.read_bytes() == data
            print(f"{name} {digest} {'ok' if same else 'DIFFERS'}")
            status |= 0 if same else 1
        else:
            DATA_DIR.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
            print(f"{name} {digest} ({len(data)} bytes)")
    return status


if __name__ == "__main__":
    sys.exit(main())
