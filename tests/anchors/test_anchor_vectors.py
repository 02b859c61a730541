"""Every anchor conformance vector decodes to its recorded result (spec/FORMAT.md §17)."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.errors import CsgsError
from tests.conformance import VECTORS_DIR
from tests.conformance.anchors import anchor_digest

VECTORS = sorted((VECTORS_DIR / "anchors").glob("*.json"))


def test_the_anchor_vector_set_is_present():
    assert {p.stem for p in VECTORS} >= {"anchors_semantic_q5", "anchors_color_q8",
                                         "anchors_color_q8_mlp_float16",
                                         "anchors_missing_features"}


def test_the_vectors_cover_both_mlp_payload_versions():
    from csgs_codec.format import read_layers

    versions = set()
    for meta_path in VECTORS:
        data = meta_path.with_suffix(".csgs").read_bytes()
        if not json.loads(meta_path.read_text())["valid"]:
            continue
        container = read_layers(data, layers="color")
        versions |= {bytes(container.payloads[e.index])[0] for e in container.toc
                     if e.type == "AMLP"}
    assert versions == {1, 2}


@pytest.mark.parametrize("meta_path", VECTORS, ids=lambda p: p.stem)
def test_vector_decodes_as_recorded(meta_path):
    meta = json.loads(meta_path.read_text())
    data = meta_path.with_suffix(".csgs").read_bytes()
    assert hashlib.sha256(data).hexdigest() == meta["sha256"]
    for read in meta["reads"]:
        if read["outcome"] == "error":
            with pytest.raises(CsgsError) as info:
                AnchorDecoder().decode(data, layers=read["layers"])
            assert type(info.value).__name__ == read["error"]
            assert info.value.chunk == read["chunk"]
            continue
        scene = AnchorDecoder().decode(data, layers=read["layers"])
        assert len(scene) == read["anchors"]
        assert anchor_digest(scene) == read["digest"]
    if "arrays" in meta:
        expected = np.load(meta_path.parent / meta["arrays"])
        scene = AnchorDecoder().decode(data, layers="color,semantic")
        for name in expected.files:
            np.testing.assert_array_equal(getattr(scene, name), expected[name])
