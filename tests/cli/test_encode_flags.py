"""`csgs encode --fast` and `--lambda L`: they reach the encoders, combine only as allowed."""

from __future__ import annotations

import pytest

from csgs_cli.main import main
from csgs_cli.scene_input import load_anchor_scene
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.interchange.ply_io import read_ply, write_ply
from csgs_codec.interchange.scaffold_io import write_scaffold
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.codec.helpers import random_scene


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path = tmp_path_factory.mktemp("flags") / "scene.ply"
    write_ply(random_scene(300, sh_degree=0, seed=2), path)
    return path


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=40, seed=6)
    return write_scaffold(scene, tmp_path_factory.mktemp("flags") / "ckpt")


def test_lambda_flag_round_trip_on_a_3dgs_scene(ply, tmp_path, capsys):
    out = tmp_path / "l.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--lambda", "0.5", "--fast", "-q"]) == 0
    assert "rate control: lambda 0.5" in capsys.readouterr().out
    data = out.read_bytes()
    scene = read_ply(ply)
    assert data == Encoder(lambda_=0.5, fast=True).encode(scene)
    assert len(Decoder().decode(data)) == len(scene)


def test_fast_flag_on_a_3dgs_preset_encode_gives_the_preset_file(ply, tmp_path):
    out = tmp_path / "f.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--fast", "--quality", "3", "-q"]) == 0
    assert out.read_bytes() == Encoder(quality=3).encode(read_ply(ply))


@pytest.mark.parametrize("other", [["--quality", "5"], ["--target-psnr", "40"]])
def test_lambda_with_quality_or_target_exits_2_and_writes_nothing(ply, tmp_path, capsys,
                                                                  other):
    out = tmp_path / "x.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--lambda", "1", *other, "-q"]) == 2
    assert "--lambda excludes" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("value", ["0", "-2", "nan", "inf"])
def test_a_bad_lambda_exits_2_naming_lambda(ply, checkpoint, tmp_path, capsys, value):
    for source in (ply, checkpoint):
        out = tmp_path / "x.csgs"
        assert main(["encode", str(source), "-o", str(out), f"--lambda={value}", "-q"]) == 2
        assert "lambda" in capsys.readouterr().err
        assert not out.exists()


def test_fast_flag_round_trip_on_an_anchor_scene(checkpoint, tmp_path, capsys):
    out = tmp_path / "a.csgs"
    assert main(["encode", str(checkpoint), "-o", str(out), "--fast", "-q"]) == 0
    assert "80 anchors" in capsys.readouterr().out
    scene = load_anchor_scene(checkpoint)
    expected = AnchorEncoder(fast=True).encode_with_report(scene)
    assert out.read_bytes() == expected.data
    decoded = AnchorDecoder().decode(out, layers="color,semantic")
    assert (decoded.features == expected.reconstruction.features).all()


def test_lambda_flag_round_trip_on_an_anchor_scene(checkpoint, tmp_path):
    out = tmp_path / "a.csgs"
    assert main(["encode", str(checkpoint), "-o", str(out), "--lambda", "4e-4", "--fast",
                 "-q"]) == 0
    scene = load_anchor_scene(checkpoint)
    assert out.read_bytes() == AnchorEncoder(lambda_=4e-4, fast=True).encode(scene)


def test_target_psnr_is_refused_for_anchor_scenes(checkpoint, tmp_path, capsys):
    out = tmp_path / "a.csgs"
    assert main(["encode", str(checkpoint), "-o", str(out), "--target-psnr", "40", "-q"]) == 2
    assert "anchor scenes" in capsys.readouterr().err
    assert not out.exists()


def test_near_lossless_quality_codes_a_3dgs_scene_and_is_refused_for_anchors(
        ply, checkpoint, tmp_path, capsys):
    out = tmp_path / "q11.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--quality", "11", "--fast", "-q"]) == 0
    assert out.read_bytes() == Encoder(quality=11, fast=True).encode(read_ply(ply))
    refused = tmp_path / "anchors.csgs"
    assert main(["encode", str(checkpoint), "-o", str(refused), "--quality", "10",
                 "-q"]) == 2
    assert "anchor scenes take quality 1..9" in capsys.readouterr().err
    assert not refused.exists()


def test_step_allocation_flags_reach_the_encoder_and_the_report(tmp_path, capsys):
    ply = tmp_path / "sh.ply"
    scene = random_scene(1100, sh_degree=1, seed=9)
    write_ply(scene, ply)
    scene = read_ply(ply)
    on, off = tmp_path / "on.csgs", tmp_path / "off.csgs"
    assert main(["encode", str(ply), "-o", str(on), "--no-hyperprior", "-q"]) == 0
    assert "step allocation: " in capsys.readouterr().out
    assert on.read_bytes() == Encoder(hyperprior=False).encode(scene)
    assert main(["encode", str(ply), "-o", str(off), "--no-hyperprior", "-q",
                 "--no-step-allocation"]) == 0
    assert "step allocation" not in capsys.readouterr().out
    assert off.read_bytes() == Encoder(hyperprior=False, step_allocation=False).encode(scene)
