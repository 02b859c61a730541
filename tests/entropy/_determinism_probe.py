"""Subprocess probe: prints SHA-256 of network outputs (both paths) and of a residual stream.

Run as ``python -m tests.entropy._determinism_probe``; the thread-count environment variables
are set by the caller before numpy loads its BLAS.
"""

from __future__ import annotations

import hashlib
import json
import pickle

import numpy as np

from csgs_codec.entropy.residual import encode_residuals
from tests.entropy._intnet_cases import random_network, random_positions


def main() -> None:
    """Compute the digests and print them as one JSON line."""
    net = random_network(11, width=64)
    x = random_positions(20000, 12)
    fast = net.forward(x, "float64")
    ref = net.forward(x, "int64")
    pickled = pickle.loads(pickle.dumps(net)).forward(x, "float64")
    mean, scale, step = fast[:, 0], fast[:, 1], fast[:, 2]
    values = mean + np.random.default_rng(13).integers(-5000, 5000, mean.size)
    stream = encode_residuals(values, mean, scale, step)
    digest = {name: hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()
              for name, a in (("float64", fast), ("int64", ref), ("pickled", pickled))}
    digest["stream"] = hashlib.sha256(stream).hexdigest()
    print(json.dumps(digest))


if __name__ == "__main__":
    main()
