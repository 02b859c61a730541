"""Several Python threads may share a Decoder, or run Encoders, at once (a service answering
requests does): every result is what one thread alone gets, bit for bit."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.interchange.ply_io import ply_bytes, read_ply
from tests.codec.helpers import SHORT_PRIOR_FIT
from tests.conftest import REPO, SAMPLE
from tests.threads import on_threads

SCENE_VECTORS = REPO / "spec" / "vectors" / "scenes"
SH3_CAPTURE = REPO / "benchmarks" / "data" / "yashica_t4_top8192.ply"


def test_one_decoder_shared_by_threads_decodes_every_vector_as_recorded():
    import json

    cases = []
    for name in ("donut_q3", "donut_q7", "far_floaters_q5", "scored_steps_q5"):
        doc = json.loads((SCENE_VECTORS / f"{name}.json").read_text())
        data = (SCENE_VECTORS / f"{name}.csgs").read_bytes()
        cases += [(data, read["layers"], read["ply_sha256"]) for read in doc["reads"]
                  if read["outcome"] == "ok"]
    decoder = Decoder()

    def digest(case):
        return hashlib.sha256(ply_bytes(decoder.decode(case[0], layers=case[1]))).hexdigest()

    results = on_threads(digest, cases * 3, threads=6)
    assert results == [expected for _, _, expected in cases * 3]


@pytest.fixture(scope="module")
def small_scenes():
    """A 3,000-Gaussian part of the sample (SH 0) and a 1,024-Gaussian part of the SH-3
    capture, whose default encode probes step allocations by rendering (numba kernels)."""
    sample = read_ply(SAMPLE)
    capture = read_ply(SH3_CAPTURE)
    return [sample.subset(np.arange(0, len(sample), len(sample) // 3000)[:3000]),
            capture.subset(np.arange(0, len(capture), 8))]


@pytest.mark.slow  # the capture's allocation probes take 3-4 s an encode on the CPU box
def test_encoders_on_threads_write_the_bytes_of_one_thread(small_scenes):
    def encode(scene) -> str:
        return hashlib.sha256(Encoder(prior_fit=SHORT_PRIOR_FIT).encode(scene)).hexdigest()

    alone = [encode(scene) for scene in small_scenes]
    together = on_threads(encode, small_scenes * 2, threads=4)
    assert together == alone * 2
