"""`csgs encode` / `csgs decode` on Scaffold-GS anchor scenes (checkpoint folder or anchor PLY)."""

from __future__ import annotations

import numpy as np

from csgs_cli.main import main
from csgs_cli.scene_input import is_anchor_input
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.interchange.anchor_ply import read_anchor_ply
from csgs_codec.interchange.scaffold_io import read_scaffold, write_scaffold
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.conftest import SAMPLE


def _checkpoint(tmp_path):
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=60, seed=3)
    return scene, write_scaffold(scene, tmp_path / "ckpt")


def test_anchor_inputs_are_recognised(tmp_path):
    _, folder = _checkpoint(tmp_path)
    assert is_anchor_input(folder) and is_anchor_input(folder / "point_cloud.ply")
    assert not is_anchor_input(SAMPLE)


def test_a_checkpoint_folder_encodes_and_decodes_through_the_cli(tmp_path, capsys):
    scene, folder = _checkpoint(tmp_path)
    out = tmp_path / "a.csgs"
    assert main(["encode", str(folder), "-o", str(out), "--quality", "6", "-q"]) == 0
    assert "120 anchors" in capsys.readouterr().out
    expected = AnchorDecoder().decode(out)
    assert main(["decode", str(out), "-o", str(tmp_path / "back.ply"), "-q"]) == 0
    back = read_anchor_ply(tmp_path / "back.ply")
    assert np.array_equal(back.positions, expected.positions)
    assert np.array_equal(back.features, expected.features)
    assert main(["decode", str(out), "-o", str(tmp_path / "back_ckpt"), "-q"]) == 0
    again = read_scaffold(tmp_path / "back_ckpt")
    assert np.array_equal(again.scaling, expected.scaling)
    assert again.mlps is not None and len(again) == len(scene)


def test_gaussian_only_options_are_refused_for_anchor_scenes(tmp_path, capsys):
    _, folder = _checkpoint(tmp_path)
    out = tmp_path / "a.csgs"
    assert main(["encode", str(folder), "-o", str(out), "--prune-opacity", "0.1", "-q"]) == 2
    assert "anchor scenes" in capsys.readouterr().err
    assert not out.exists()


def test_select_takes_an_anchor_bitstream_and_render_refuses_it(tmp_path, capsys):
    _, folder = _checkpoint(tmp_path)
    out = tmp_path / "a.csgs"
    assert main(["encode", str(folder), "-o", str(out), "-q"]) == 0
    capsys.readouterr()
    assert main(["render", str(out), "--orbit", "1", "-o", str(tmp_path / "r"), "-q"]) == 2
    assert "anchor scene" in capsys.readouterr().err
    assert main(["select", str(out), "--view", "orbit:0", "--size", "64x48", "--click",
                 "32,24", "-o", str(tmp_path / "sel.ply"), "-q"]) == 0
    assert (tmp_path / "sel.ply").exists()
