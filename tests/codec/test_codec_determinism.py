"""Decoding is bit-identical under other thread counts, and never imports torch."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

from csgs_codec.codec.encoder import Encoder
from csgs_codec.interchange.ply_io import read_ply
from tests.conftest import REPO, SAMPLE

PROBE = """
import hashlib, sys
from csgs_codec.codec.decoder import Decoder
from csgs_codec.interchange.ply_io import ply_bytes
scene = Decoder().decode(sys.argv[1], layers="color,semantic")
print(hashlib.sha256(ply_bytes(scene)).hexdigest())
print("torch" in sys.modules)
"""


def decode_in_subprocess(path, threads: int) -> tuple[str, bool]:
    env = dict(os.environ)
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                "NUMBA_NUM_THREADS"):
        env[var] = str(threads)
    out = subprocess.run([sys.executable, "-c", PROBE, str(path)], capture_output=True,
                         text=True, env=env, cwd=REPO, check=True)
    digest, torch_loaded = out.stdout.split()
    return digest, torch_loaded == "True"


def test_decode_is_identical_with_one_and_two_threads_and_imports_no_torch(tmp_path):
    from csgs_codec.interchange.ply_io import ply_bytes

    result = Encoder(quality=6).encode_with_report(read_ply(SAMPLE))
    path = tmp_path / "donut.csgs"
    path.write_bytes(result.data)
    expected = hashlib.sha256(ply_bytes(result.reconstruction)).hexdigest()
    one, torch_one = decode_in_subprocess(path, 1)
    two, torch_two = decode_in_subprocess(path, 2)
    assert one == two == expected
    assert not torch_one and not torch_two


def test_encoding_twice_gives_the_same_bytes(default_encoding):
    """The session's default encode of the sample (tests/conftest.py), made again."""
    _, first = default_encoding(SAMPLE)
    assert Encoder().encode(read_ply(SAMPLE)) == first.data
