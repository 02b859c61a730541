"""Conformance vectors in spec/vectors/container/ decode exactly as their JSON says.

The vectors are read, never regenerated, here: `python -m tests.conformance
--regenerate --only container` is the only thing that writes them.
"""

from __future__ import annotations

import hashlib
import json

import pytest

from csgs_codec.errors import FormatError
from csgs_codec.format import read_layers
from tests.conformance import VECTORS_DIR
from tests.conformance.container import run_read

CONTAINER_VECTORS = VECTORS_DIR / "container"
REQUIRED = ["empty_scene", "unknown_optional_chunk", "unknown_critical_chunk", "bad_chunk_crc",
            "truncated_toc", "truncated_after_color"]


def _vector_names() -> list[str]:
    return sorted(path.stem for path in CONTAINER_VECTORS.glob("*.json"))


def test_required_container_vectors_exist():
    names = _vector_names()
    for name in REQUIRED:
        assert name in names
        assert (CONTAINER_VECTORS / f"{name}.csgs").is_file()


def test_there_are_valid_and_invalid_vectors():
    docs = [json.loads((CONTAINER_VECTORS / f"{n}.json").read_text()) for n in _vector_names()]
    assert {doc["valid"] for doc in docs} == {True, False}


@pytest.mark.parametrize("name", _vector_names())
def test_vector_decodes_as_recorded(name):
    doc = json.loads((CONTAINER_VECTORS / f"{name}.json").read_text())
    data = (CONTAINER_VECTORS / doc["file"]).read_bytes()
    assert doc["schema"] == "csgs-vector/1"
    assert len(data) == doc["bytes"]
    assert hashlib.sha256(data).hexdigest() == doc["sha256"]
    assert doc["reads"]
    for expected in doc["reads"]:
        assert run_read(data, expected["layers"]) == expected


def _check_read(source, expected: dict) -> None:
    if expected["outcome"] == "ok":
        got = read_layers(source, expected["layers"])
        assert sorted(got.payloads) == [p["index"] for p in expected["decode"]["payloads"]]
    else:
        with pytest.raises(FormatError) as info:
            read_layers(source, expected["layers"])
        assert (info.value.offset, info.value.chunk) == (expected["offset"], expected["chunk"])


@pytest.mark.parametrize("name", _vector_names())
def test_vector_decodes_the_same_from_a_path_and_a_file(name):
    doc = json.loads((CONTAINER_VECTORS / f"{name}.json").read_text())
    path = CONTAINER_VECTORS / doc["file"]
    for expected in doc["reads"]:
        _check_read(path, expected)
        with open(path, "rb") as handle:
            _check_read(handle, expected)
