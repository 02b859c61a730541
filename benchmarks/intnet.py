"""Integer network inference benchmark: anchor evaluations per second.

    .venv/bin/python benchmarks/intnet.py [--n 1000000] [--repeat 3] [--out FILE]

A 3-layer width-64 integer MLP (L = 4 octaves, 24 -> 64 -> 64 -> 3, 8-bit weights, 12-bit
activations), random weights, uniformly random 16-bit positions. Checks the float64 (BLAS)
path against the int64 reference on a subset before timing; times the float64 path on N
anchors (wall time, and process CPU time: on a shared machine anchors per CPU-second is the
figure less distorted by other load) and the int64 path on N / 10. The thread count is
whatever numpy's BLAS uses (set OMP_NUM_THREADS / OPENBLAS_NUM_THREADS to pin it).
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

from csgs_codec.entropy.intnet import IntLayer, IntMLP


def benchmark_network(seed: int = 0) -> IntMLP:
    """The 3-layer width-64 network measured here."""
    rng = np.random.default_rng(seed)
    widths = [24, 64, 64, 3]
    layers = tuple(IntLayer(rng.integers(-128, 128, (widths[i + 1], widths[i])),
                            rng.integers(-(1 << 16), 1 << 16, widths[i + 1]), 11, 8)
                   for i in range(3))
    return IntMLP(16, 4, 12, layers, np.array([-(1 << 20), 0, 0]),
                  np.array([1 << 20, 63, 175]))


def best_time(fn, repeat: int) -> float:
    """Fastest of ``repeat`` calls of ``fn``, in seconds."""
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def best_cpu_time(fn, repeat: int) -> float:
    """Smallest process CPU time (all threads) of ``repeat`` calls: robust to other load."""
    best = math.inf
    for _ in range(repeat):
        start = time.process_time()
        fn()
        best = min(best, time.process_time() - start)
    return best


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print (or write) one csgs-bench/1 JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    net = benchmark_network()
    x = np.random.default_rng(1).integers(0, 1 << 16, (args.n, 3))
    check = x[:20000]
    assert np.array_equal(net.forward(check, "float64"), net.forward(check, "int64"))
    small = x[:max(args.n // 10, 1)]
    embed_s = best_time(lambda: net.embed(x), args.repeat)
    fast = best_time(lambda: net.forward(x, "float64"), args.repeat)
    fast_cpu = best_cpu_time(lambda: net.forward(x, "float64"), args.repeat)
    ref = best_time(lambda: net.forward(small, "int64"), args.repeat)
    rows = [
        {"case": "mlp3_w64_float64", "anchors": args.n, "layers": [24, 64, 64, 3],
         "forward_s": fast, "forward_cpu_s": fast_cpu, "embed_s": embed_s,
         "manchors_per_s": args.n / fast / 1e6,
         "manchors_per_cpu_s": args.n / fast_cpu / 1e6},
        {"case": "mlp3_w64_int64", "anchors": small.shape[0], "layers": [24, 64, 64, 3],
         "forward_s": ref, "manchors_per_s": small.shape[0] / ref / 1e6},
    ]
    emit(document("intnet", rows, blas_threads=os.environ.get("OPENBLAS_NUM_THREADS")), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
