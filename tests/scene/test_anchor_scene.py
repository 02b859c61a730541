"""AnchorScene rules, the anchor PLY layout and the synthetic anchor generator (no torch)."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.anchor_ply import (
    MASK_LOGIT_THRESHOLD,
    anchor_ply_bytes,
    parse_anchor_ply,
    read_anchor_ply,
    write_anchor_ply,
)
from csgs_codec.interchange.ply_header import parse_header
from csgs_codec.scene.anchor_scene import AnchorScene, default_semantic_names
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene


def tiny_scene(m: int = 3, f: int = 4, k: int = 2, seed: int = 0) -> AnchorScene:
    rng = np.random.default_rng(seed)
    return AnchorScene(
        positions=rng.standard_normal((m, 3)).astype(np.float32),
        features=rng.standard_normal((m, f)).astype(np.float32),
        offsets=rng.standard_normal((m, k, 3)).astype(np.float32),
        scaling=rng.standard_normal((m, 6)).astype(np.float32),
        offset_mask=np.ones((m, k), bool))


# --------------------------------------------------------------------------- data class
def test_gaussian_positions_are_anchor_plus_offset_times_exp_scaling():
    scene = tiny_scene(m=1, k=2)
    scene.positions[:] = [1.0, 2.0, 3.0]
    scene.scaling[0, :3] = np.log([0.5, 2.0, 4.0])
    scene.offsets[0] = [[1.0, 1.0, 1.0], [-2.0, 0.5, 0.25]]
    expected = np.array([[[1.5, 4.0, 7.0], [0.0, 3.0, 4.0]]], np.float32)
    np.testing.assert_allclose(scene.gaussian_positions(), expected, rtol=1e-6)


def test_validate_names_property_and_first_bad_anchor():
    scene = tiny_scene(m=5)
    scene.offsets[3, 1, 2] = np.nan
    scene.offsets[4, 0, 0] = np.inf
    with pytest.raises(InputError) as err:
        scene.validate("scene.ply")
    assert err.value.property == "offsets" and err.value.index == 3
    assert "scene.ply" in str(err.value)


@pytest.mark.parametrize("name, value", [
    ("scaling", np.zeros((3, 5), np.float32)),
    ("offset_mask", np.ones((3, 2), np.uint8)),
    ("features", np.zeros((3, 4), np.float64)),
    ("offsets", np.zeros((3, 2, 2), np.float32)),
])
def test_validate_rejects_wrong_shape_or_dtype(name, value):
    scene = tiny_scene()
    setattr(scene, name, value)
    with pytest.raises(InputError) as err:
        scene.validate()
    assert err.value.property == name


def test_validate_requires_one_name_per_semantic_channel():
    scene = tiny_scene()
    scene.semantic = np.zeros((3, 6), np.float32)
    scene.semantic_names = default_semantic_names(5)
    with pytest.raises(InputError, match="6 channels but 5 names"):
        scene.validate()


def test_subset_keeps_rows_of_every_array():
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=20, with_mlps=False)
    keep = scene.labels == 1
    part = scene.subset(keep)
    assert len(part) == 20 and np.all(part.labels == 1)
    assert np.array_equal(part.offsets, scene.offsets[keep])
    assert np.array_equal(part.offset_mask, scene.offset_mask[keep])


# --------------------------------------------------------------------------- anchor PLY
def test_anchor_ply_uses_official_property_order():
    scene = tiny_scene(f=3, k=2)
    names = [p.name for p in parse_header(anchor_ply_bytes(scene)).element("vertex").properties]
    assert names == (["x", "y", "z", "nx", "ny", "nz"]
                     + [f"f_offset_{i}" for i in range(6)]
                     + [f"f_anchor_feat_{i}" for i in range(3)]
                     + ["opacity"] + [f"scale_{i}" for i in range(6)]
                     + [f"rot_{i}" for i in range(4)])


def test_anchor_ply_stores_offsets_transposed():
    scene = tiny_scene(m=1, f=1, k=2)
    scene.offsets[0] = [[1, 2, 3], [4, 5, 6]]
    data = anchor_ply_bytes(scene)
    header = parse_header(data)
    row = np.frombuffer(data, header.element("vertex").dtype("<"), 1, header.header_bytes)
    stored = [float(row[f"f_offset_{j}"][0]) for j in range(6)]
    assert stored == [1, 4, 2, 5, 3, 6]  # f_offset_{c*K + k} = offset k, coordinate c


def test_anchor_ply_round_trip_is_exact(tmp_path):
    scene = synthetic_anchor_scene(n_objects=3, anchors_per_object=30, with_mlps=False)
    write_anchor_ply(scene, tmp_path / "anchors.ply")
    back = read_anchor_ply(tmp_path / "anchors.ply")
    assert back.equals(scene)


def test_anchor_ply_without_masked_offsets_has_no_mask_properties():
    scene = tiny_scene()
    assert b"f_mask_" not in anchor_ply_bytes(scene)
    scene.offset_mask[1, 0] = False
    assert b"property float f_mask_1" in anchor_ply_bytes(scene)
    back = parse_anchor_ply(anchor_ply_bytes(scene))
    assert np.array_equal(back.offset_mask, scene.offset_mask)


def test_hac_mask_logits_keep_offsets_above_sigmoid_one_percent():
    scene = tiny_scene(m=1, k=2)
    scene.offset_mask[0, 1] = False
    data = bytearray(anchor_ply_bytes(scene))
    header = parse_header(bytes(data))
    rows = np.frombuffer(data, header.element("vertex").dtype("<"), 1, header.header_bytes)
    rows["f_mask_0"] = MASK_LOGIT_THRESHOLD + 1e-3  # sigmoid just above 0.01: kept
    rows["f_mask_1"] = MASK_LOGIT_THRESHOLD - 1e-3  # just below: masked
    assert parse_anchor_ply(bytes(data)).offset_mask.tolist() == [[True, False]]


def _drop_property(data: bytes, name: str) -> bytes:
    """Rewrite an anchor PLY without property ``name``."""
    header = parse_header(data)
    vertex = header.element("vertex")
    rows = np.frombuffer(data, vertex.dtype("<"), vertex.count, header.header_bytes)
    keep = [p.name for p in vertex.properties if p.name != name]
    text = data[:header.header_bytes].decode().replace(f"property float {name}\n", "")
    out = np.empty(vertex.count, [(n, "<f4") for n in keep])
    for n in keep:
        out[n] = rows[n]
    return text.encode() + out.tobytes()


@pytest.mark.parametrize("missing", ["y", "f_anchor_feat_0", "scale_5", "f_offset_3"])
def test_missing_property_is_named(missing):
    data = _drop_property(anchor_ply_bytes(tiny_scene(f=4, k=2)), missing)
    with pytest.raises(InputError) as err:
        parse_anchor_ply(data, source="anchors.ply")
    assert err.value.property == missing and err.value.file == "anchors.ply"


def test_offset_count_not_multiple_of_three_is_rejected():
    data = _drop_property(anchor_ply_bytes(tiny_scene(k=2)), "f_offset_5")
    with pytest.raises(InputError, match="3 x K") as err:
        parse_anchor_ply(data, source="anchors.ply")
    assert err.value.property == "f_offset_0"


def test_truncated_anchor_ply_is_rejected_before_allocation():
    data = anchor_ply_bytes(tiny_scene())
    with pytest.raises(InputError, match="truncated") as err:
        parse_anchor_ply(data[:-1], source="anchors.ply")
    assert err.value.offset is not None


def test_huge_declared_count_is_rejected():
    data = anchor_ply_bytes(tiny_scene()).replace(b"element vertex 3", b"element vertex 3000000000")
    with pytest.raises(InputError, match="declares 3000000000 rows"):
        parse_anchor_ply(data, source="anchors.ply")


def test_non_finite_value_names_property_and_anchor():
    scene = tiny_scene(m=4, f=4)
    data = bytearray(anchor_ply_bytes(scene))
    header = parse_header(bytes(data))
    rows = np.frombuffer(data, header.element("vertex").dtype("<"), 4, header.header_bytes)
    rows["f_anchor_feat_2"][2] = np.nan
    with pytest.raises(InputError) as err:
        parse_anchor_ply(bytes(data), source="anchors.ply")
    assert (err.value.property, err.value.index) == ("f_anchor_feat_2", 2)


def test_semantic_names_must_read_back_as_semantic():
    scene = tiny_scene()
    scene.semantic = np.zeros((3, 1), np.float32)
    scene.semantic_names = ("color_hint",)
    with pytest.raises(InputError) as err:
        anchor_ply_bytes(scene)
    assert err.value.property == "color_hint"


def test_ascii_anchor_ply_reads_like_binary():
    scene = tiny_scene(m=2, f=2, k=1)
    data = anchor_ply_bytes(scene)
    header = parse_header(data)
    vertex = header.element("vertex")
    rows = np.frombuffer(data, vertex.dtype("<"), 2, header.header_bytes)
    text = data[:header.header_bytes].decode().replace("binary_little_endian", "ascii")
    body = "".join(" ".join(repr(float(rows[p.name][i])) for p in vertex.properties) + "\n"
                   for i in range(2))
    back = parse_anchor_ply((text + body).encode())
    assert back.equals(scene)


# --------------------------------------------------------------------------- synthetic
def test_synthetic_scene_is_deterministic_and_valid():
    a = synthetic_anchor_scene(n_objects=3, anchors_per_object=40, seed=7)
    b = synthetic_anchor_scene(n_objects=3, anchors_per_object=40, seed=7)
    c = synthetic_anchor_scene(n_objects=3, anchors_per_object=40, seed=8)
    a.validate()
    assert a.equals(b) and not a.equals(c)
    assert (a.feat_dim, a.n_offsets, a.semantic.shape[1]) == (50, 10, 6)


def test_synthetic_anchors_sit_on_distinct_voxels():
    scene = synthetic_anchor_scene(n_objects=4, anchors_per_object=50, voxel_size=0.02,
                                   with_mlps=False)
    cells = scene.positions / 0.02
    assert np.allclose(cells, np.round(cells), atol=1e-3)
    assert len(np.unique(np.round(cells), axis=0)) == len(scene)


def test_synthetic_objects_have_one_label_and_separable_semantics():
    scene = synthetic_anchor_scene(n_objects=5, anchors_per_object=60, with_mlps=False)
    assert np.bincount(scene.labels).tolist() == [60] * 5
    unit = scene.semantic / np.linalg.norm(scene.semantic, axis=1, keepdims=True)
    means = np.stack([unit[scene.labels == i].mean(0) for i in range(5)])
    nearest = np.argmax(unit @ means.T, axis=1)
    assert np.array_equal(nearest, scene.labels)


def test_synthetic_features_are_correlated_across_channel_groups():
    scene = synthetic_anchor_scene(n_objects=5, anchors_per_object=100, with_mlps=False)
    f = scene.features.astype(np.float64)
    later, earlier = f[:, 10:20], f[:, :10]
    # Least-squares prediction of group 2 from group 1 removes most of its variance.
    coef, *_ = np.linalg.lstsq(np.c_[earlier, np.ones(len(f))], later, rcond=None)
    residual = later - np.c_[earlier, np.ones(len(f))] @ coef
    assert residual.var() < 0.5 * later.var()


def test_synthetic_scene_masks_about_the_requested_fraction():
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=200, masked_fraction=0.3,
                                   with_mlps=False)
    assert 0.25 < 1 - scene.offset_mask.mean() < 0.35


def test_unknown_anchor_property_is_dropped_with_a_warning():
    from csgs_codec.errors import CsgsWarning

    scene = tiny_scene(m=2)
    data = anchor_ply_bytes(scene)
    header = parse_header(data)
    vertex = header.element("vertex")
    rows = np.frombuffer(data, vertex.dtype("<"), 2, header.header_bytes)
    wider = np.empty(2, vertex.dtype("<").descr + [("extra", "<f4")])
    for p in vertex.properties:
        wider[p.name] = rows[p.name]
    wider["extra"] = 1.0
    text = data[:header.header_bytes].decode().replace(
        "end_header", "property float extra\nend_header")
    with pytest.warns(CsgsWarning, match="extra"):
        back = parse_anchor_ply(text.encode() + wider.tobytes(), source="anchors.ply")
    assert back.equals(scene)
