"""`csgs encode` / `csgs decode`: outputs, messages, exit codes and no half-written files."""

from __future__ import annotations

import json

import numpy as np

from csgs_cli.main import main
from csgs_codec.interchange.ply_io import read_ply, write_ply
from tests.codec.helpers import random_scene
from tests.conftest import SAMPLE, fixture


def test_encode_info_decode_round_trip(tmp_path, capsys, default_encoding):
    out = tmp_path / "donut.csgs"
    assert main(["encode", str(SAMPLE), "-o", str(out), "--quiet"]) == 0
    # What the command writes by default is what Encoder() writes: the tests that share the
    # session's default encodes (tests/conftest.py) test what users make.
    assert out.read_bytes() == default_encoding(SAMPLE)[1].data
    printed = capsys.readouterr().out
    assert "bits/Gaussian" in printed and "45,624 Gaussians" in printed
    assert main(["info", str(out), "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert {c["type"] for c in facts["chunks"]} >= {"SCNE", "GEOM", "SHDC", "ROTN"}
    ply = tmp_path / "back.ply"
    assert main(["decode", str(out), "-o", str(ply), "--quiet"]) == 0
    back = read_ply(ply)
    original = read_ply(SAMPLE)
    assert len(back) == len(original)
    lo, hi = original.bounding_box()
    assert np.all(back.positions >= lo - 1e-4) and np.all(back.positions <= hi + 1e-4)


def test_semantic_layer_through_the_cli(tmp_path, capsys):
    src = tmp_path / "sem.ply"
    write_ply(random_scene(400, semantic=3, labels=True), src)
    out = tmp_path / "sem.csgs"
    assert main(["encode", str(src), "-o", str(out), "-q"]) == 0
    assert main(["decode", str(out), "-o", str(tmp_path / "c.ply"), "-q"]) == 0
    assert read_ply(tmp_path / "c.ply").semantic is None
    assert main(["decode", str(out), "-o", str(tmp_path / "s.ply"), "--layers",
                 "color,semantic", "-q"]) == 0
    full = read_ply(tmp_path / "s.ply")
    assert full.semantic.shape == (400, 3) and full.labels is not None


def test_bad_ply_gives_exit_2_and_no_output(tmp_path, capsys):
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 5\n"
                    b"property float x\nend_header\n")
    out = tmp_path / "out.csgs"
    assert main(["encode", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.ply" in err and "Traceback" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == [bad]


def test_damaged_csgs_gives_exit_2_and_no_output(tmp_path, capsys):
    good = tmp_path / "good.csgs"
    assert main(["encode", str(fixture("three_points_sh3.ply")), "-o", str(good), "-q"]) == 0
    data = bytearray(good.read_bytes())
    data[-10] ^= 0x40
    bad = tmp_path / "bad.csgs"
    bad.write_bytes(bytes(data))
    out = tmp_path / "out.ply"
    assert main(["decode", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.csgs" in err and "chunk" in err and "Traceback" not in err
    assert not out.exists()


def test_decode_of_a_ply_is_a_clear_error(tmp_path, capsys):
    assert main(["decode", str(SAMPLE), "-o", str(tmp_path / "x.ply")]) == 2
    assert "donut.ply" in capsys.readouterr().err


def test_info_reports_bits_per_gaussian_per_chunk(tmp_path, capsys):
    out = tmp_path / "three.csgs"
    assert main(["encode", str(fixture("three_points_sh3.ply")), "-o", str(out), "-q"]) == 0
    capsys.readouterr()
    assert main(["info", str(out), "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["gaussians"] == 3 and facts["sh_degree_coded"] == 3
    shbc = next(c for c in facts["chunks"] if c["type"] == "SHBC")
    assert shbc["bits_per_gaussian"] == 8 * shbc["bytes"] / 3
    assert facts["bits_per_gaussian"] == 8 * out.stat().st_size / 3
    assert main(["info", str(out)]) == 0
    assert "bits/G" in capsys.readouterr().out


def test_target_psnr_through_the_cli(tmp_path, capsys):
    src = tmp_path / "small.ply"
    write_ply(random_scene(1500), src)
    out = tmp_path / "t.csgs"
    assert main(["encode", str(src), "-o", str(out), "--target-psnr", "35", "-q"]) == 0
    printed = capsys.readouterr().out
    assert "rate control:" in printed and "target 35.00 dB" in printed
    assert main(["encode", str(src), "-o", str(tmp_path / "bad.csgs"), "--target-psnr",
                 "500", "-q"]) == 2
    assert "target PSNR" in capsys.readouterr().err
    assert not (tmp_path / "bad.csgs").exists()
