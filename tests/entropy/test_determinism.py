"""Determinism: identical indices and bitstreams across BLAS thread counts, paths, pickling."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import REPO
from tests.entropy._intnet_cases import random_network, random_positions

THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def _probe(threads: int) -> dict:
    env = dict(os.environ, **{name: str(threads) for name in THREAD_VARS})
    done = subprocess.run([sys.executable, "-m", "tests.entropy._determinism_probe"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_outputs_and_streams_are_identical_under_1_and_2_blas_threads():
    one, two = _probe(1), _probe(2)
    assert one == two
    assert one["float64"] == one["int64"] == one["pickled"]


def test_decode_modules_do_not_import_torch():
    code = ("import sys, csgs_codec.entropy, csgs_codec.entropy.intnet_bytes, "
            "csgs_codec.entropy.residual, csgs_codec.entropy.tables; "
            "print('torch' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


@pytest.mark.gpu
def test_cuda_float64_inference_matches_numpy_exactly():
    import torch

    net = random_network(21)
    x = random_positions(50000, 22)
    h = torch.from_numpy(net.embed(x).astype(np.float64)).cuda()
    torch.backends.cuda.matmul.allow_tf32 = False
    for i, layer in enumerate(net.layers):
        w = torch.from_numpy(np.ldexp(layer.weights.T.astype(np.float64), -layer.shift)).cuda()
        half = (1 << (layer.shift - 1)) if layer.shift else 0
        off = torch.from_numpy(np.ldexp((layer.biases + half).astype(np.float64),
                                        -layer.shift)).cuda()
        acc = torch.floor(h @ w + off)
        if i == len(net.layers) - 1:
            lo = torch.from_numpy(net.out_lo.astype(np.float64)).cuda()
            hi = torch.from_numpy(net.out_hi.astype(np.float64)).cuda()
            h = torch.maximum(torch.minimum(acc, hi), lo)
        else:
            h = acc.clamp(0, (1 << net.act_bits) - 1)
    assert np.array_equal(h.cpu().numpy().astype(np.int64), net.forward(x, "int64"))
