"""`csgs compare`: identical scenes score infinite PSNR and SSIM 1; a known color shift scores
the PSNR it must."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.metrics.comparison import compare_scenes
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.orbit import look_at, orbit_cameras
from tests.conftest import SAMPLE
from tests.render.synthetic import SH_C0, blob_scene

SHIFT = 0.05  # rendered color shift of a fully opaque pixel


def compare_json(capsys, *argv) -> dict:
    assert main(["compare", "--quiet", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def shifted(scene, shift=SHIFT):
    candidate = scene.subset(np.arange(len(scene)))
    candidate.sh_dc = candidate.sh_dc + np.float32(shift / SH_C0)
    return candidate


def test_compare_identical_files_gives_infinite_psnr_and_ssim_one(tmp_path, capsys):
    path = tmp_path / "x.ply"
    write_ply(blob_scene(), path)
    facts = compare_json(capsys, str(path), str(path), "--orbit", "4", "--size", "64x48")
    assert facts["mean"] == {"psnr": "inf", "ssim": 1.0, "foreground_psnr": "inf"}
    assert len(facts["views"]) == 4
    assert all(v["psnr"] == "inf" and v["ssim"] == 1.0 for v in facts["views"])
    assert facts["matching"]["method"] == "identity"
    assert all(e["max_abs"] == 0 for e in facts["attribute_errors"].values())


def test_compare_sample_with_itself(capsys):
    facts = compare_json(capsys, str(SAMPLE), str(SAMPLE), "--orbit", "1", "--size", "64x48",
                         "--no-attributes")
    assert facts["mean"]["psnr"] == "inf" and facts["mean"]["ssim"] == 1.0
    assert facts["attribute_errors"] is None
    assert all(0.02 < v["foreground_fraction"] < 0.9 for v in facts["views"])


def test_color_shift_gives_psnr_of_shift_times_opacity():
    # The renderer is linear in color: shifting every Gaussian's color by s shifts each
    # pixel by s * alpha, so MSE = s^2 mean(alpha^2) over pixels (and channels).
    from csgs_codec.render.rasterizer import render

    scene = blob_scene(count=300)
    candidate = shifted(scene)
    cameras = orbit_cameras(scene, 3, width=64, height=48)
    report = compare_scenes(scene, candidate, cameras)
    for camera, view in zip(cameras, report.views):
        alpha = render(scene, camera).alpha.astype(np.float64)
        mask = alpha > 0.05
        expected = -10 * math.log10(SHIFT**2 * np.mean(alpha**2))
        expected_fg = -10 * math.log10(SHIFT**2 * np.mean(alpha[mask] ** 2))
        assert view.psnr == pytest.approx(expected, abs=0.1)
        assert view.foreground_psnr == pytest.approx(expected_fg, abs=0.1)
        assert view.ssim < 1.0


def test_color_shift_on_opaque_frame_gives_minus_twenty_log_shift(tmp_path, capsys):
    # Large opaque Gaussians filling the whole frame: every pixel moves by exactly SHIFT,
    # so PSNR = -20 log10(SHIFT) = 26.02 dB.
    rng = np.random.default_rng(4)
    scene = blob_scene(count=800, log_scale=np.log(0.3), opacity_logit=8.0)
    scene.positions[:] = rng.uniform(-1, 1, size=(800, 3)).astype(np.float32)
    camera = Camera(48, 36, 60.0, 60.0, 24.0, 18.0,
                    look_at(np.array([0.0, 0.0, 2.5]), np.zeros(3), np.array([0.0, 1.0, 0.0])))
    report = compare_scenes(scene, shifted(scene), [camera], attributes=False)
    (view,) = report.views
    assert view.foreground_fraction == 1.0 and view.psnr == view.foreground_psnr
    assert view.psnr == pytest.approx(-20 * math.log10(SHIFT), abs=0.1)
    assert view.foreground_psnr == pytest.approx(-20 * math.log10(SHIFT), abs=0.1)


def test_compare_cli_reports_color_shift_and_attribute_error(tmp_path, capsys):
    scene = blob_scene()
    write_ply(scene, tmp_path / "a.ply")
    write_ply(shifted(scene), tmp_path / "b.ply")
    facts = compare_json(capsys, str(tmp_path / "a.ply"), str(tmp_path / "b.ply"),
                         "--orbit", "2", "--size", "64x48")
    assert 20 < facts["mean"]["psnr"] < 60 and facts["mean"]["ssim"] < 1
    assert facts["mean"]["foreground_psnr"] < facts["mean"]["psnr"]  # black border flatters
    assert facts["attribute_errors"]["sh_dc"]["max_abs"] == pytest.approx(SHIFT / SH_C0,
                                                                          rel=1e-5)


def test_compare_text_output_names_the_headline(tmp_path, capsys):
    path = tmp_path / "x.ply"
    write_ply(blob_scene(count=50), path)
    assert main(["compare", "--quiet", str(path), str(path), "--orbit", "2",
                 "--size", "32x24"]) == 0
    out = capsys.readouterr().out
    assert "headline: foreground PSNR inf dB" in out and "orbit_001" in out
    assert "matched by identity" in out


def test_compare_notes_different_gaussian_counts(tmp_path, capsys):
    scene = blob_scene(count=100)
    write_ply(scene, tmp_path / "a.ply")
    write_ply(scene.subset(np.arange(50)), tmp_path / "b.ply")
    facts = compare_json(capsys, str(tmp_path / "a.ply"), str(tmp_path / "b.ply"),
                         "--orbit", "1", "--size", "32x24")
    assert facts["matching"]["method"] == "nearest neighbour"
    assert "counts differ (100 vs 50)" in facts["notes"][0]


def test_compare_rejects_a_damaged_candidate(tmp_path, capsys):
    path = tmp_path / "x.ply"
    write_ply(blob_scene(count=10), path)
    (tmp_path / "x.csgs").write_bytes(b"\x89CSG")
    assert main(["compare", str(path), str(tmp_path / "x.csgs")]) == 2
    err = capsys.readouterr().err
    assert "x.csgs" in err and "Traceback" not in err


def test_compare_scores_a_decoded_bitstream(tmp_path, capsys):
    from csgs_codec.codec.encoder import Encoder

    path = tmp_path / "x.ply"
    scene = blob_scene(count=50)
    write_ply(scene, path)
    (tmp_path / "x.csgs").write_bytes(Encoder(quality=9).encode(scene))
    assert main(["compare", str(path), str(tmp_path / "x.csgs"), "--orbit", "2", "--size",
                 "64x48", "--json", "--quiet"]) == 0
    facts = json.loads(capsys.readouterr().out)
    mean_psnr = facts["mean"]["psnr"]
    assert mean_psnr == "inf" or float(mean_psnr) > 35
