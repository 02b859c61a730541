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
    (["--budget", "1m", "--resume", "--checkpoint-dir", "ck"], "budget"),
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


@pytest.mark.parametrize("budget, fragment", [("5s", "10 s to 7 days"),
                                              ("soon", "not a duration")])
def test_a_bad_budget_exits_2_naming_it(dataset, tmp_path, capsys, budget, fragment):
    with pytest.raises(SystemExit) as info:  # argparse's refusal of the value
        main(["train", str(dataset), "-o", str(tmp_path / "x.csgs"), "--budget", budget])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--budget" in err and fragment in err


@pytest.mark.slow  # runs for its budget, 15 s
def test_a_time_budget_sets_stage_1_from_its_first_steps(dataset, tmp_path, capsys):
    """`--budget 15s` on a tiny capture: stage 1's steps are planned from the probe's speed
    (more than the probe's 40 on any machine this fast, never the default 2,000 it would
    take without the budget), the run ends and writes a file that decodes."""
    from csgs_codec.train.pipeline import BUDGET_PROBE_STEPS

    out = tmp_path / "budget.csgs"
    assert main(["train", str(dataset), "-o", str(out), "--budget", "15s", "--anchors", "50",
                 "--features", "8", "--offsets", "4", "--semantic-iterations", "15",
                 "--test-every", "3", "-q"]) == 0
    printed = capsys.readouterr().out
    line = next(x for x in printed.splitlines() if x.startswith("budget 15 s"))
    steps = int(line.split("ran ")[1].split(" steps")[0].replace(",", ""))
    assert steps > BUDGET_PROBE_STEPS
    assert len(AnchorDecoder().decode(out.read_bytes())) > 0


def test_budget_iterations_follow_the_probe_speed():
    from csgs_codec.train.pipeline import (
        BUDGET_MAX_ITERATIONS,
        BUDGET_PROBE_STEPS,
        BUDGET_STAGE1_SHARE,
        budget_iterations,
    )

    assert budget_iterations(10.0, 600.0) == int(10 * 600 * BUDGET_STAGE1_SHARE)
    assert budget_iterations(10.0, 0.5) == BUDGET_PROBE_STEPS + 1
    assert budget_iterations(10.0, -5.0) == BUDGET_PROBE_STEPS + 1
    assert budget_iterations(1e9, 3600.0) == BUDGET_MAX_ITERATIONS
