"""Residual coder benchmark: throughput and size against the ideal information content.

    .venv/bin/python benchmarks/entropy_coder.py [--n 1000000] [--repeat 3] [--out FILE]

Rows:
* ``table_model``: 10^6 residuals drawn from the frozen tables themselves (scale index
  uniform over the 64 tables); size against -sum log2(f / 2^16), the ideal for the model the
  coder is given. Throughput of the grouped coder (``encode_symbols`` / ``decode_symbols``,
  escapes included) in M symbols/s.
* ``gaussian_data`` / ``laplacian_data``: residuals of continuous Gaussian / Laplacian values
  with log-uniform sigma in [0.2, 100] steps, each coded with the nearest Gaussian table;
  size against the ideal -sum log2 P(bin) of the true distribution (what the table family
  loses to its scale grid, tail range and 16-bit precision, or to a Laplacian source).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import document, emit  # noqa: E402

from csgs_codec.entropy.residual import decode_symbols, encode_symbols
from csgs_codec.entropy.tables import gaussian_family, scale_index


def best_time(fn, repeat: int) -> float:
    """Fastest of ``repeat`` calls of ``fn``, in seconds."""
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def sample_from_tables(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    """Residuals drawn from the tables' own frequencies; returns r, scale, ideal bits."""
    family = gaussian_family()
    scale = rng.integers(0, family.count, n)
    r = np.empty(n, dtype=np.int64)
    ideal = 0.0
    for s in range(family.count):
        where = np.flatnonzero(scale == s)
        f = family.freqs[s]
        half = int(family.half_widths[s])
        sym = rng.choice(f.size - 1, size=where.size, p=f[:-1] / f[:-1].sum())
        r[where] = sym - half
        ideal += float(-np.log2(f[sym] / 65536.0).sum())
    return r, scale, ideal


def _bin_mass(r: np.ndarray, sigma: np.ndarray, kind: str) -> np.ndarray:
    from scipy.special import ndtr  # benchmark only

    lo, hi = (r - 0.5) / sigma, (r + 0.5) / sigma
    if kind == "gaussian":
        return ndtr(hi) - ndtr(lo)
    b = sigma / math.sqrt(2.0)  # Laplacian with the same standard deviation

    def cdf(x):
        return np.where(x < 0, 0.5 * np.exp(x * sigma / b), 1 - 0.5 * np.exp(-x * sigma / b))
    return cdf(hi) - cdf(lo)


def data_row(kind: str, n: int, rng: np.random.Generator) -> dict:
    """Code continuous-source residuals with the nearest table; compare with the ideal."""
    sigma = np.exp(rng.uniform(math.log(0.2), math.log(100.0), n))
    noise = rng.normal(size=n) if kind == "gaussian" else rng.laplace(size=n) / math.sqrt(2)
    r = np.floor(noise * sigma + 0.5).astype(np.int64)
    scale = scale_index(sigma)
    data = encode_symbols(r, scale)
    assert np.array_equal(decode_symbols(data, scale), r)
    ideal = float(-np.log2(np.maximum(_bin_mass(r, sigma, "gaussian" if kind == "gaussian"
                                                else "laplacian"), 1e-300)).sum())
    half = gaussian_family().half_widths[scale]
    return {"case": f"{kind}_data", "symbols": n, "bytes": len(data),
            "bits_per_symbol": 8 * len(data) / n, "ideal_bits_per_symbol": ideal / n,
            "overhead_pct": 100 * (8 * len(data) / ideal - 1),
            "escape_fraction": float(np.mean(np.abs(r) > half))}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print (or write) one csgs-bench/1 JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(2026)
    r, scale, ideal = sample_from_tables(args.n, rng)
    data = encode_symbols(r, scale)
    assert np.array_equal(decode_symbols(data, scale), r), "round trip failed"
    enc = best_time(lambda: encode_symbols(r, scale), args.repeat)
    dec = best_time(lambda: decode_symbols(data, scale), args.repeat)
    rows = [{"case": "table_model", "symbols": args.n, "tables": 64, "precision_bits": 16,
             "bytes": len(data), "ideal_bytes": ideal / 8,
             "overhead_pct": 100 * (8 * len(data) / ideal - 1),
             "encode_s": enc, "decode_s": dec,
             "encode_msym_per_s": args.n / enc / 1e6, "decode_msym_per_s": args.n / dec / 1e6}]
    rows += [data_row(kind, args.n, rng) for kind in ("gaussian", "laplacian")]
    emit(document("entropy_coder", rows), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
