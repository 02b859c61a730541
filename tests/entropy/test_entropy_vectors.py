"""Conformance vectors in spec/vectors/entropy/ decode (and re-encode) as recorded."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from csgs_codec.entropy.intnet_bytes import intnet_from_bytes, intnet_to_bytes
from csgs_codec.entropy.residual import decode_residuals, encode_residuals
from csgs_codec.entropy.tables import GAUSSIAN_V1_SHA256, SINE_V1_SHA256, gaussian_family
from csgs_codec.errors import CsgsError
from tests.conformance import VECTORS_DIR

VECTORS = VECTORS_DIR / "entropy"
DOCS = sorted(VECTORS.glob("*.json"))


def _load(path):
    doc = json.loads(path.read_text())
    data = (VECTORS / doc["file"]).read_bytes() if "file" in doc else None
    if data is not None:
        assert hashlib.sha256(data).hexdigest() == doc["sha256"]
    return doc, data


def _ints(values):
    return np.array(values, dtype=np.int64)


def test_vector_folder_holds_tables_residual_and_network_vectors():
    names = {p.stem for p in DOCS}
    assert {"tables", "residual_escapes", "residual_mixed", "intnet_small"} <= names


def test_table_vector_matches_the_frozen_tables():
    doc, _ = _load(VECTORS / "tables.json")
    assert doc["gaussian_v1"]["sha256"] == GAUSSIAN_V1_SHA256
    assert doc["sine_v1"]["sha256"] == SINE_V1_SHA256
    assert doc["gaussian_v1"]["half_widths"] == gaussian_family().half_widths.tolist()


@pytest.mark.parametrize("path", [p for p in DOCS if p.stem.startswith("residual")],
                         ids=lambda p: p.stem)
def test_residual_vector_decodes_as_recorded(path):
    doc, data = _load(path)
    inputs = doc["inputs"]
    args = (_ints(inputs["mean"]), _ints(inputs["scale_idx"]), _ints(inputs["step_idx"]))
    if doc["outcome"] == "ok":
        assert decode_residuals(data, *args).tolist() == doc["decoded"]
        assert encode_residuals(_ints(inputs["values"]), *args) == data
    else:
        with pytest.raises(CsgsError) as info:
            decode_residuals(data, *args)
        assert type(info.value).__name__ == doc["error"]
        assert info.value.offset == doc["offset"]


@pytest.mark.parametrize("path", [p for p in DOCS if p.stem.startswith("intnet")],
                         ids=lambda p: p.stem)
def test_network_vector_decodes_as_recorded(path):
    doc, data = _load(path)
    if doc["outcome"] == "ok":
        net = intnet_from_bytes(data)
        positions = _ints(doc["positions"])
        assert net.embed(positions[:1])[0].tolist() == doc["embedding_first_row"]
        for route in ("float64", "int64"):
            assert net.forward(positions, route).tolist() == doc["outputs"]
        assert intnet_to_bytes(net, data[0]) == data  # re-encodes to the same bytes
    else:
        with pytest.raises(CsgsError) as info:
            intnet_from_bytes(data)
        assert type(info.value).__name__ == doc["error"]
        assert info.value.offset == doc["offset"]
