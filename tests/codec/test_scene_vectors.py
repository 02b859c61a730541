"""Every scene conformance vector decodes to its recorded result (spec/FORMAT.md §14)."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.errors import CsgsError
from csgs_codec.interchange.ply_io import ply_bytes
from tests.conformance import RETIRED_SCENE_VECTORS, VECTORS_DIR, current

VECTORS = current(sorted((VECTORS_DIR / "scenes").glob("*.json")))


def test_the_scene_vector_set_is_present():
    names = {p.stem for p in VECTORS}
    assert {"donut_q3", "donut_q7", "three_points_sh3_q9", "semantic_small",
            "missing_opacity_chunk"} <= names


@pytest.mark.parametrize("meta_path", VECTORS, ids=lambda p: p.stem)
def test_vector_decodes_as_recorded(meta_path):
    meta = json.loads(meta_path.read_text())
    data = meta_path.with_suffix(".csgs").read_bytes()
    assert hashlib.sha256(data).hexdigest() == meta["sha256"]
    for read in meta["reads"]:
        if read["outcome"] == "error":
            with pytest.raises(CsgsError) as info:
                Decoder().decode(data, layers=read["layers"], lod=read.get("lod"))
            assert type(info.value).__name__ == read["error"]
            assert info.value.chunk == read["chunk"]
            continue
        scene = Decoder().decode(data, layers=read["layers"], lod=read.get("lod"))
        assert len(scene) == read["gaussians"]
        assert hashlib.sha256(ply_bytes(scene)).hexdigest() == read["ply_sha256"]
    if "arrays" in meta:
        expected = np.load(meta_path.parent / meta["arrays"])
        scene = Decoder().decode(data, layers="color,semantic")
        for name in expected.files:
            if name.startswith("instance_"):  # the instance table's arrays (SEMC embeddings)
                value = getattr(scene.instances, name.removeprefix("instance_"))
            else:
                value = getattr(scene, name)
            np.testing.assert_array_equal(value, expected[name])


@pytest.mark.parametrize("stem", sorted(RETIRED_SCENE_VECTORS))
def test_retired_vectors_are_kept_as_they_landed(stem):
    """Vectors are never deleted: the drafts' vectors stay, byte for byte (spec/CHANGES.md
    revision 21 says why they are no longer decoded)."""
    meta = json.loads((VECTORS_DIR / "scenes" / f"{stem}.json").read_text())
    data = (VECTORS_DIR / "scenes" / f"{stem}.csgs").read_bytes()
    assert hashlib.sha256(data).hexdigest() == meta["sha256"] and len(data) == meta["bytes"]
