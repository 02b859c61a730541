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
    assert main(["decode", str(out), "-o", str(tmp_path / "back_ckpt"), "-q"]) == 0
    back = read_anchor_ply(tmp_path / "back_ckpt" / "point_cloud.ply")
    assert np.array_equal(back.positions, expected.positions)
    assert np.array_equal(back.features, expected.features)
    again = read_scaffold(tmp_path / "back_ckpt")
    assert np.array_equal(again.scaling, expected.scaling)
    assert again.mlps is not None and len(again) == len(scene)


def test_gaussian_only_options_are_refused_for_anchor_scenes(tmp_path, capsys):
    _, folder = _checkpoint(tmp_path)
    out = tmp_path / "a.csgs"
    assert main(["encode", str(folder), "-o", str(out), "--prune-opacity", "0.1", "-q"]) == 2
    assert "anchor scenes" in capsys.readouterr().err
    assert not out.exists()


def test_every_command_takes_anchor_files_plys_and_checkpoints(tmp_path, capsys):
    import json

    from csgs_codec import read_scene
    from csgs_codec.model.anchor_views import SceneViews
    from csgs_codec.render.image_io import load_png
    from csgs_codec.render.rasterizer import render
    from csgs_codec.scene.orbit import orbit_cameras

    _, folder = _checkpoint(tmp_path)
    out = tmp_path / "a.csgs"
    assert main(["encode", str(folder), "-o", str(out), "-q"]) == 0
    assert main(["decode", str(out), "--layers", "color,semantic", "-o",
                 str(tmp_path / "back"), "-q"]) == 0
    capsys.readouterr()
    decoded = AnchorDecoder().decode(out)
    views = SceneViews(decoded)
    camera = orbit_cameras(views.framing(), 2, width=64, height=48)[1]
    exact = np.clip(render(views.gaussians(camera), camera, backend="numba").image, 0, 1)
    for source in (out, tmp_path / "back", tmp_path / "back" / "point_cloud.ply"):
        target = tmp_path / f"r_{source.name}"
        assert main(["render", str(source), "--orbit", "2", "--size", "64x48", "-o",
                     str(target), "-q"]) == 0
        image = load_png(target / "orbit_001.png")
        assert np.abs(image - exact).max() <= 1 / 255 + 1e-6  # the exact per-view render
        assert main(["info", str(source), "--json"]) == 0
        facts = json.loads(capsys.readouterr().out)
        if source.suffix == ".csgs":
            assert "ANCH" in json.dumps(facts)
        else:
            assert facts["anchors"] == len(decoded)
        assert main(["select", str(source), "--view", "orbit:0", "--size", "64x48",
                     "--click", "32,24", "-o", str(tmp_path / "sel.ply"), "-q"]) == 0
        assert len(read_scene(tmp_path / "sel.ply")) > 0
        capsys.readouterr()
    assert main(["compare", str(out), str(tmp_path / "back"), "--orbit", "2", "--size",
                 "64x48", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["mean"]["psnr"] == "inf"  # the same anchors rendered the same way
    assert main(["decode", str(out), "-o", str(tmp_path / "baked.spz"), "--refine-bake", "40",
                 "-q"]) == 0
    capsys.readouterr()
    assert main(["compare", str(out), str(tmp_path / "baked.spz"), "--orbit", "2", "--size",
                 "64x48", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mean"]["foreground_psnr"] > 30


def test_decode_bakes_anchor_files_into_every_scene_format(tmp_path, capsys):
    from csgs_codec import read_scene

    _, folder = _checkpoint(tmp_path)
    out = tmp_path / "a.csgs"
    assert main(["encode", str(folder), "-o", str(out), "-q"]) == 0
    for name in ("a.ply", "a.spz", "a.glb", "a.splat"):
        assert main(["decode", str(out), "-o", str(tmp_path / name), "--sh-degree", "1",
                     "--refine-bake", "0" if name != "a.ply" else "20", "-q"]) == 0
        assert (tmp_path / name).is_file()  # a scene file, never a checkpoint folder
        assert len(read_scene(tmp_path / name)) > 0
    assert read_scene(tmp_path / "a.ply").sh_degree_stored == 1
    assert main(["decode", str(out), "-o", str(tmp_path / "b.spz"), "--checkpoint",
                 str(tmp_path / "ckpt_too"), "--refine-bake", "0", "-q"]) == 0
    assert read_scaffold(tmp_path / "ckpt_too").mlps is not None
    capsys.readouterr()
    assert main(["decode", str(SAMPLE_CSGS(tmp_path)), "-o", str(tmp_path / "s.ply"),
                 "--sh-degree", "1"]) == 2
    assert "--sh-degree" in capsys.readouterr().err


def SAMPLE_CSGS(tmp_path):  # noqa: N802
    path = tmp_path / "sample.csgs"
    if not path.exists():
        assert main(["encode", str(SAMPLE), "-o", str(path), "--fast", "-q"]) == 0
    return path


def test_refine_bake_0_writes_the_api_s_bake_and_bad_values_exit_2(tmp_path, capsys):
    """`--refine-bake 0` is the browser page's bake (bake_anchor_scene's default settings);
    the default refines it; a negative count is refused before any work."""
    from csgs_codec import read_scene
    from csgs_codec.bake.anchor_bake import bake_anchor_scene

    _, folder = _checkpoint(tmp_path)
    out = tmp_path / "a.csgs"
    assert main(["encode", str(folder), "-o", str(out), "-q"]) == 0
    assert main(["decode", str(out), "-o", str(tmp_path / "plain.ply"), "--refine-bake", "0",
                 "-q"]) == 0
    expected = bake_anchor_scene(AnchorDecoder().decode(out))
    plain = read_scene(tmp_path / "plain.ply")
    np.testing.assert_array_equal(plain.sh_dc, expected.sh_dc)
    np.testing.assert_array_equal(plain.opacity, expected.opacity)
    assert main(["decode", str(out), "-o", str(tmp_path / "refined.ply"), "--refine-bake",
                 "30"]) == 0
    assert "refined in 30 steps" in capsys.readouterr().out
    refined = read_scene(tmp_path / "refined.ply")
    np.testing.assert_array_equal(refined.positions, plain.positions)
    assert not np.array_equal(refined.opacity, plain.opacity)
    assert main(["decode", str(out), "-o", str(tmp_path / "bad.ply"), "--refine-bake",
                 "-1"]) == 2
    assert "refine" in capsys.readouterr().err and not (tmp_path / "bad.ply").exists()


def test_the_semantic_layer_left_out_is_said_only_where_the_output_could_carry_it(
        tmp_path, capsys):
    from benchmarks._js_receiver import REPO

    trained = REPO / "tests" / "data" / "anchors" / "demo_trained.csgs"
    for name, said in (("a.ply", True), ("a.spz", False)):
        assert main(["decode", str(trained), "-o", str(tmp_path / name), "--refine-bake",
                     "0"]) == 0
        assert ("--layers color,semantic" in capsys.readouterr().err) == said, name
