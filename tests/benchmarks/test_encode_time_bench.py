"""benchmarks/encode_time.py: its row describes the encode it timed (the file's size and hash
are the encoder's output) and the allocation it ran."""

from __future__ import annotations

import hashlib

import pytest

from benchmarks.encode_time import find_scene, measure
from csgs_codec import read_scene
from csgs_codec.codec.encoder import Encoder


@pytest.mark.slow  # two encodes and an allocation: 13 s on the 2-core box
def test_a_row_names_the_encoders_bytes_and_the_allocation():
    path = find_scene("yashica_t4_top8192")
    assert path is not None, "the repository keeps this capture in benchmarks/data"
    row = measure(path, 5, 1, keep=1500)
    scene = read_scene(path)
    scene = scene.subset(list(range(1500)))
    data = Encoder(quality=5).encode(scene)
    assert row["gaussians"] == 1500 and row["sh_degree"] == 3 and row["quality"] == 5
    assert row["bytes"] == len(data) and row["sha256"] == hashlib.sha256(data).hexdigest()
    assert row["allocation_trials"] > 5 and row["encode_s"] > 0 and row["allocation_s"] > 0
    assert set(row["allocation_offsets"]) <= {"dc", "rest1", "rest2", "rest3", "opacity",
                                              "scale", "rot", "position"}


def test_an_absent_scene_is_not_found():
    assert find_scene("no_such_scene") is None
