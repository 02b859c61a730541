"""``read_scene`` / ``detect_format``: every format recognised by its content, the extension
used only where the content cannot tell (``.splat``), clear errors for the rest."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from csgs_codec import read_scene as lazy_read_scene
from csgs_codec.codec.encoder import Encoder
from csgs_codec.codec.files import read_scene, read_scene_with_report
from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.format import MAGIC
from csgs_codec.interchange import detect_format
from tests.interchange.helpers import DATA, matched

CONTENT = {"brush_sh3.ply": "ply", "brush_sh3.compressed.ply": "ply",
           "brush_sh3.v2.spz": "spz", "brush_sh3.v3.spz": "spz", "brush_sh3.v4.spz": "spz",
           "brush_sh3.sog": "sog", "brush_sh3.l0.ksplat": "ksplat",
           "brush_sh3.l1.ksplat": "ksplat", "brush_sh3.l2.ksplat": "ksplat",
           "brush_sh3.glb": "glb"}


@pytest.mark.parametrize("name", sorted(CONTENT))
def test_the_content_decides_not_the_extension(name, tmp_path):
    renamed = tmp_path / "scene.bin"
    shutil.copy(DATA / name, renamed)
    assert detect_format(renamed) == CONTENT[name]
    scene, source = read_scene_with_report(renamed)
    assert len(scene) == 200
    assert source.format == ("compressed-ply" if "compressed" in name else CONTENT[name])


def test_splat_has_no_header_so_its_extension_names_it(tmp_path):
    assert detect_format(DATA / "donut_sh0.splat") == "splat"
    renamed = tmp_path / "scene.bin"
    shutil.copy(DATA / "donut_sh0.splat", renamed)
    with pytest.raises(UnsupportedError, match="neither a .csgs bitstream"):
        detect_format(renamed)


def test_sog_folders_and_their_meta_json(tmp_path):
    assert detect_format(DATA / "donut_sh0_sog") == "sog"
    assert detect_format(DATA / "donut_sh0_sog" / "meta.json") == "sog"
    assert len(read_scene(DATA / "donut_sh0_sog" / "meta.json")) == 300
    with pytest.raises(InputError, match="without meta.json"):
        detect_format(tmp_path)


def test_csgs_is_decoded_and_the_magic_comes_from_the_format_package(tmp_path):
    brush = read_scene(DATA / "brush_sh3.ply")
    path = tmp_path / "scene.data"
    path.write_bytes(Encoder(quality=9, hyperprior=False).encode(brush))
    assert path.read_bytes().startswith(MAGIC)
    scene, source = read_scene_with_report(path)
    assert source.format == "csgs" and len(scene) == 200
    original = matched(brush, scene)  # the decoder returns the Gaussians in octree order
    assert np.abs(scene.positions - original.positions).max() < 1e-2


def test_the_package_exports_read_scene():
    assert lazy_read_scene is read_scene


def test_missing_empty_and_unknown_files(tmp_path):
    with pytest.raises(InputError, match="file not found") as err:
        read_scene(tmp_path / "missing.spz")
    assert err.value.file == str(tmp_path / "missing.spz")
    (tmp_path / "empty.spz").write_bytes(b"")
    with pytest.raises(InputError, match="empty file"):
        read_scene(tmp_path / "empty.spz")
    (tmp_path / "mesh.obj").write_bytes(b"v 0 0 0\n")
    with pytest.raises(UnsupportedError) as err:
        read_scene(tmp_path / "mesh.obj")
    assert err.value.offset == 0 and "SPZ" in str(err.value)
    (tmp_path / "scene.gltf").write_text("{}")
    with pytest.raises(UnsupportedError, match="binary .glb"):
        read_scene(tmp_path / "scene.gltf")


def test_a_missing_optional_package_names_the_extra(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "zstandard", None)  # import raises ImportError
    with pytest.raises(UnsupportedError, match=r"'formats' extra.*csgs\[formats\]"):
        read_scene(DATA / "brush_sh3.v4.spz")
    monkeypatch.setitem(sys.modules, "PIL.Image", None)
    with pytest.raises(UnsupportedError, match="'formats' extra"):
        read_scene(DATA / "brush_sh3.sog")
    assert len(read_scene(DATA / "brush_sh3.v3.spz")) == 200  # gzip: no extra needed


def test_a_csgs_file_reads_its_color_layer_by_default_as_the_decoder_does(tmp_path):
    from csgs_codec import Decoder, Encoder
    from tests.conformance.scenes import small_semantic_scene

    path = tmp_path / "semantic.csgs"
    path.write_bytes(Encoder(quality=6).encode(small_semantic_scene()))
    plain = read_scene(path)
    assert plain.semantic is None and plain.equals(Decoder().decode(path))
    both = read_scene(path, layers="color,semantic")
    assert both.semantic is not None
    assert both.equals(Decoder().decode(path, layers="color,semantic"))
