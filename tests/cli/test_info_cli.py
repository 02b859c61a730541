"""`csgs info` on PLY scenes and the CLI's error contract (one line, exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec import __version__
from tests.conftest import SAMPLE, fixture, shared_path
from tests.scene.ply_samples import make_ply, property_names, random_values


def run_json(capsys, *argv) -> dict:
    assert main(["info", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_info_playbot_reports_count_and_degree(capsys):
    facts = run_json(capsys, str(shared_path("scenes", "playbot.ply")))
    assert facts["gaussians"] == 248155
    assert facts["sh_degree_stored"] == 2 and facts["sh_degree_in_use"] == 2


def test_info_zero_sh_tile_reports_degree_three_stored_zero_in_use(capsys):
    facts = run_json(capsys, str(fixture("flat_tile_zero_sh.ply")))
    assert facts["sh_degree_stored"] == 3 and facts["sh_degree_in_use"] == 0
    assert facts["zero_sh_bands"] == [1, 2, 3]


def test_info_sample_reports_real_ranges(capsys):
    facts = run_json(capsys, str(SAMPLE))
    assert facts["gaussians"] == 45624
    assert facts["attributes"]["opacity"]["channels"] == 1
    assert facts["robust"]["extent"] == pytest.approx(0.2, abs=0.02)
    lo, hi = facts["bounding_box"]["min"], facts["bounding_box"]["max"]
    assert all(a < b for a, b in zip(lo, hi))


def test_info_text_output_names_the_facts(capsys):
    assert main(["info", str(SAMPLE)]) == 0
    out = capsys.readouterr().out
    assert "45,624" in out and "SH degree" in out and "robust extent" in out


def test_info_lists_semantic_channels(tmp_path, capsys):
    names = property_names(extra=("ins_feat_0", "ins_feat_1"))
    path = tmp_path / "sem.ply"
    path.write_bytes(make_ply(random_values(3, names), names))
    facts = run_json(capsys, str(path))
    assert facts["semantic_channels"] == ["ins_feat_0", "ins_feat_1"]


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.ply"
    path.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\n")
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.ply" in err and "Traceback" not in err


def test_nan_fails_unless_sanitized(tmp_path, capsys):
    names = property_names()
    values = random_values(4, names)
    values[2, 0] = np.nan
    path = tmp_path / "nan.ply"
    path.write_bytes(make_ply(values, names))
    assert main(["info", str(path)]) == 2
    assert "index 2" in capsys.readouterr().err
    facts = run_json(capsys, str(path), "--sanitize")
    assert facts["gaussians"] == 3 and facts["nonfinite_dropped"] == 1


def test_version_and_missing_file_through_the_installed_command(tmp_path):
    out = subprocess.run([sys.executable, "-m", "csgs_cli.main", "--version"],
                         capture_output=True, text=True)
    assert out.returncode == 0 and __version__ in out.stdout
    out = subprocess.run([sys.executable, "-m", "csgs_cli.main", "info",
                          str(tmp_path / "missing.ply")], capture_output=True, text=True)
    assert out.returncode == 2
    assert "missing.ply: file not found" in out.stderr and "Traceback" not in out.stderr


def test_debug_shows_traceback(tmp_path, capsys):
    assert main(["info", str(tmp_path / "missing.ply"), "--debug"]) == 2
    assert "Traceback" in capsys.readouterr().err


def test_quiet_silences_warnings(tmp_path, capsys):
    names = property_names(extra=("red",))
    path = tmp_path / "w.ply"
    path.write_bytes(make_ply(random_values(2, names), names))
    assert main(["info", str(path), "--quiet"]) == 0
    assert "red" not in capsys.readouterr().err
    assert main(["info", str(path)]) == 0
    assert "ignoring unknown PLY properties: red" in capsys.readouterr().err


def test_info_on_a_csgs_file_lists_layers_and_chunks(tmp_path, capsys):
    from csgs_codec.format import Chunk, write_container

    path = tmp_path / "scene.bin"  # detected by its magic, not its extension
    write_container([Chunk("fill", "base", b"abc"), Chunk("fill", "color", bytes(100)),
                     Chunk("fill", "semantic", bytes(10))], path=path)
    facts = run_json(capsys, str(path))
    assert facts["kind"] == "csgs" and facts["version"] == "1.0"
    assert [c["layer"] for c in facts["chunks"]] == ["base", "color", "semantic"]
    assert facts["layers"]["color"]["payload_bytes"] == 100
    assert main(["info", str(path)]) == 0
    assert "semantic" in capsys.readouterr().out


def test_info_on_a_damaged_csgs_is_a_format_error(tmp_path, capsys):
    from csgs_codec.format import Chunk, write_container

    data = bytearray(write_container([Chunk("fill", "base", b"abc")]))
    data[12] ^= 0xFF  # the TOC size field
    path = tmp_path / "bad.csgs"
    path.write_bytes(bytes(data))
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert "bad.csgs" in err and "byte" in err and "Traceback" not in err


def test_quiet_works_before_the_command(tmp_path, capsys):
    names = property_names(extra=("red",))
    path = tmp_path / "w.ply"
    path.write_bytes(make_ply(random_values(2, names), names))
    assert main(["--quiet", "info", str(path)]) == 0
    assert "red" not in capsys.readouterr().err


def test_info_says_which_sh_bands_are_in_opponent_colours(capsys):
    from tests.conftest import REPO

    vectors = REPO / "spec" / "vectors" / "scenes"
    facts = run_json(capsys, str(vectors / "sh_colour_transform_q5.csgs"))
    assert facts["sh_opponent_bands"] == [1, 2, 3]
    assert main(["info", str(vectors / "sh_colour_transform_q5.csgs")]) == 0
    assert "bands 1, 2, 3 in opponent colours" in capsys.readouterr().out
    # A file without the record, and one whose record is damaged, say nothing of it.
    assert "sh_opponent_bands" not in run_json(capsys, str(vectors / "donut_q3.csgs"))
    damaged = run_json(capsys, str(vectors / "sh_colour_transform_unknown_id.csgs"))
    assert "sh_opponent_bands" not in damaged
