"""Encoding and decoding give identical bytes under other thread counts; decode never
imports torch."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

from tests.anchors.helpers import encoded
from tests.conftest import REPO

ENCODE = """
import hashlib
from tests.anchors.helpers import encoded
print(hashlib.sha256(encoded(semantic="none").data).hexdigest())
"""
DECODE = """
import hashlib, sys
from csgs_codec.codec.anchor_decoder import AnchorDecoder
s = AnchorDecoder().decode(sys.argv[1], layers="color,semantic")
parts = [s.positions, s.features, s.offsets, s.scaling, s.offset_mask, s.semantic, s.labels]
print(hashlib.sha256(b"".join(a.tobytes() for a in parts)).hexdigest())
print("torch" in sys.modules)
"""


def run(code: str, *args: str) -> list[list[str]]:
    """Run ``code`` with 1 and with 2 threads (in parallel); each run's stdout words."""
    procs = []
    for threads in (1, 2):
        env = dict(os.environ)
        for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
            env[var] = str(threads)
        procs.append(subprocess.Popen([sys.executable, "-c", code, *args], text=True,
                                      stdout=subprocess.PIPE, env=env, cwd=REPO))
    outputs = [p.communicate()[0] for p in procs]
    assert all(p.returncode == 0 for p in procs)
    return [out.split() for out in outputs]


def test_encoding_with_one_and_two_threads_gives_the_same_bytes():
    expected = hashlib.sha256(encoded(semantic="none").data).hexdigest()
    assert run(ENCODE) == [[expected], [expected]]


def test_decoding_with_one_and_two_threads_is_identical_and_imports_no_torch(tmp_path):
    result = encoded()
    path = tmp_path / "anchors.csgs"
    path.write_bytes(result.data)
    s = result.reconstruction
    parts = [s.positions, s.features, s.offsets, s.scaling, s.offset_mask, s.semantic,
             s.labels]
    expected = hashlib.sha256(b"".join(a.tobytes() for a in parts)).hexdigest()
    assert run(DECODE, str(path)) == [[expected, "False"], [expected, "False"]]
