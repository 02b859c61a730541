"""PLY reading and writing: every real file round-trips bit-exactly; every layout reads."""

from __future__ import annotations

import numpy as np
import plyfile
import pytest

from csgs_codec.interchange.ply_io import parse_ply_bytes, ply_bytes, read_ply, write_ply
from csgs_codec.scene import GaussianScene
from tests.conftest import SAMPLE, SCENES, fixture, fixture_files, shared_path
from tests.scene.ply_samples import make_ply, property_names, random_values

SHARED_FILES = sorted(SCENES.glob("*.ply")) + fixture_files()


@pytest.mark.parametrize("path", SHARED_FILES + [SAMPLE], ids=lambda p: p.name)
def test_shared_file_round_trips_bit_exactly(path, tmp_path):
    scene = read_ply(path)
    out = tmp_path / "out.ply"
    write_ply(scene, out)
    again = read_ply(out)
    assert again.equals(scene)
    assert again.positions.tobytes() == scene.positions.tobytes()


@pytest.mark.parametrize("path", SHARED_FILES, ids=lambda p: p.name)
def test_reader_agrees_with_plyfile(path):
    scene = read_ply(path)
    vertex = plyfile.PlyData.read(str(path))["vertex"]
    np.testing.assert_array_equal(scene.positions[:, 0], vertex["x"])
    np.testing.assert_array_equal(scene.opacity, vertex["opacity"])
    np.testing.assert_array_equal(scene.rotations[:, 3], vertex["rot_3"])
    b = scene.sh_rest.shape[1]
    if b:
        # f_rest is channel-major: f_rest_{b} is the green channel's first coefficient.
        np.testing.assert_array_equal(scene.sh_rest[:, 0, 1], vertex[f"f_rest_{b}"])
        np.testing.assert_array_equal(scene.sh_rest[:, b - 1, 2], vertex[f"f_rest_{3 * b - 1}"])


def test_three_points_nonstandard_order_maps_by_name():
    path = fixture("three_points_sh3.ply")
    scene = read_ply(path)
    vertex = plyfile.PlyData.read(str(path))["vertex"]
    assert len(scene) == 3 and scene.sh_degree_stored == 3
    np.testing.assert_array_equal(scene.sh_dc[:, 2], vertex["f_dc_2"])
    np.testing.assert_array_equal(scene.scales[:, 1], vertex["scale_1"])


def test_playbot_is_degree_two():
    scene = read_ply(shared_path("scenes", "playbot.ply"))
    assert len(scene) == 248155
    assert scene.sh_degree_stored == 2 and scene.sh_degree_in_use() == 2


def test_zero_sh_tile_stores_degree_three_uses_zero():
    scene = read_ply(fixture("flat_tile_zero_sh.ply"))
    assert scene.sh_degree_stored == 3
    assert scene.sh_degree_in_use() == 0
    assert scene.zero_sh_bands() == [1, 2, 3]


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("sh_rest", [0, 9, 24, 45])
def test_every_format_and_sh_degree_reads_the_same_values(fmt, sh_rest):
    names = property_names(sh_rest)
    values = random_values(5, names, seed=sh_rest)
    scene, report = parse_ply_bytes(make_ply(values, names, fmt=fmt))
    assert report.format == fmt
    assert scene.sh_degree_stored == {0: 0, 9: 1, 24: 2, 45: 3}[sh_rest]
    col = {name: values[:, i] for i, name in enumerate(names)}
    np.testing.assert_array_equal(scene.positions[:, 2], col["z"])
    np.testing.assert_array_equal(scene.rotations[:, 0], col["rot_0"])
    if sh_rest:
        b = sh_rest // 3
        np.testing.assert_array_equal(scene.sh_rest[:, 1, 0], col["f_rest_1"])
        np.testing.assert_array_equal(scene.sh_rest[:, 0, 2], col[f"f_rest_{2 * b}"])


@pytest.mark.parametrize("ply_type", ["double", "half", "uchar", "short", "int"])
def test_property_types_convert_to_float32(ply_type):
    names = property_names()
    values = np.abs(random_values(4, names)).round()
    data = make_ply(values, names, types={"opacity": ply_type, "x": ply_type})
    scene, _ = parse_ply_bytes(data)
    assert scene.opacity.dtype == np.float32
    np.testing.assert_array_equal(scene.opacity, values[:, names.index("opacity")])
    np.testing.assert_array_equal(scene.positions[:, 0], values[:, names.index("x")])


def test_any_property_order_reads_by_name():
    names = property_names(9)[::-1]
    values = random_values(6, names, seed=3)
    scene, _ = parse_ply_bytes(make_ply(values, names))
    np.testing.assert_array_equal(scene.scales[:, 2], values[:, names.index("scale_2")])
    np.testing.assert_array_equal(scene.sh_rest[:, 2, 1], values[:, names.index("f_rest_5")])


def test_semantic_properties_and_labels_are_kept_and_round_trip(tmp_path):
    names = property_names(extra=("ins_feat_0", "ins_feat_1", "sem_a", "label"))
    values = random_values(7, names)
    values[:, -1] = np.arange(7) % 3
    scene, _ = parse_ply_bytes(make_ply(values, names, types={"label": "int"}))
    assert scene.semantic_names == ("ins_feat_0", "ins_feat_1", "sem_a")
    np.testing.assert_array_equal(scene.semantic[:, 2], values[:, names.index("sem_a")])
    np.testing.assert_array_equal(scene.labels, [0, 1, 2, 0, 1, 2, 0])
    write_ply(scene, tmp_path / "s.ply")
    assert read_ply(tmp_path / "s.ply").equals(scene)


def test_unknown_properties_dropped_with_one_warning():
    names = property_names(extra=("red", "confidence"))
    values = random_values(3, names)
    with pytest.warns(UserWarning, match="red, confidence") as record:
        _, report = parse_ply_bytes(make_ply(values, names))
    assert len(record) == 1
    assert report.dropped_properties == ["red", "confidence"]


def test_other_elements_before_vertex_are_skipped():
    names = property_names()
    values = random_values(3, names)
    body = make_ply(values, names)
    header, rows = body.split(b"end_header\n", 1)
    header = header.replace(b"element vertex", b"element camera 2\nproperty float fov\n"
                            b"element vertex")
    data = header + b"end_header\n" + np.array([1.0, 2.0], "<f4").tobytes() + rows
    scene, _ = parse_ply_bytes(data)
    np.testing.assert_array_equal(scene.positions[:, 0], values[:, 0])


def test_writer_uses_inria_order():
    scene = read_ply(fixture("three_points_sh3.ply"))
    header = ply_bytes(scene).split(b"end_header")[0].decode()
    props = [ln.split()[-1] for ln in header.splitlines() if ln.startswith("property")]
    assert props == property_names(45)


def test_empty_scene_round_trips(tmp_path):
    scene = GaussianScene.empty(sh_degree=2)
    write_ply(scene, tmp_path / "e.ply")
    again = read_ply(tmp_path / "e.ply")
    assert len(again) == 0 and again.sh_degree_stored == 2


def test_write_never_leaves_partial_file(tmp_path, monkeypatch):
    scene = read_ply(fixture("three_points_sh3.ply"))
    target = tmp_path / "out.ply"
    import os

    def broken_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(Exception, match="No space left"):
        write_ply(scene, target)
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []


def test_written_file_has_ordinary_permissions(tmp_path):
    import os
    import stat

    write_ply(read_ply(fixture("three_points_sh3.ply")), tmp_path / "p.ply")
    mask = os.umask(0)
    os.umask(mask)
    mode = stat.S_IMODE((tmp_path / "p.ply").stat().st_mode)
    assert mode == 0o666 & ~mask
