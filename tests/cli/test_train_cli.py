"""`csgs synthetic` and `csgs train` through the command line."""

from __future__ import annotations

import pytest

from csgs_cli.main import main
from csgs_codec.codec.anchor_decoder import AnchorDecoder


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("synthetic")
    assert main(["synthetic", str(folder), "--views", "6", "--size", "48x36",
                 "--gaussians", "100", "-q"]) == 0
    return folder


def test_synthetic_writes_a_dataset_train_reads(dataset):
    assert (dataset / "transforms.json").is_file()
    assert (dataset / "scene.ply").is_file()
    assert len(list((dataset / "masks").glob("*.png"))) == 6


def test_train_writes_a_decodable_file_and_reports_it(dataset, tmp_path, capsys):
    out = tmp_path / "scene.csgs"
    code = main(["train", str(dataset), "-o", str(out), "--iterations", "40", "--anchors",
                 "50", "--features", "8", "--offsets", "4", "--semantic-iterations", "15",
                 "--test-every", "3", "-q"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "anchors" in printed and "held-out views: PSNR" in printed
    scene = AnchorDecoder().decode(out.read_bytes(), layers="color,semantic")
    assert scene.semantic is not None and len(scene) > 0


@pytest.mark.parametrize("arguments, fragment", [
    (["--iterations", "0"], "iterations"),
    (["--lambda", "-1"], "lambda"),
    (["--resume"], "checkpoint-dir"),
    (["--resolution", "4"], "resolution"),
])
def test_bad_options_exit_2_naming_the_option(dataset, tmp_path, capsys, arguments, fragment):
    out = tmp_path / "x.csgs"
    assert main(["train", str(dataset), "-o", str(out), "-q", *arguments]) == 2
    assert fragment in capsys.readouterr().err
    assert not out.exists()


def test_a_missing_dataset_exits_2_naming_it(tmp_path, capsys):
    assert main(["train", str(tmp_path / "nowhere"), "-o", str(tmp_path / "x.csgs"),
                 "-q"]) == 2
    assert "nowhere" in capsys.readouterr().err


def test_synthetic_refuses_a_bad_size(tmp_path, capsys):
    assert main(["synthetic", str(tmp_path / "d"), "--size", "big", "-q"]) == 2
    assert "size" in capsys.readouterr().err
