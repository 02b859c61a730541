"""`csgs render`: orbit or loaded cameras to PNG files; bad options give one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.render.image_io import load_png
from tests.conftest import REPO, SAMPLE
from tests.render.synthetic import blob_scene

CAMERA_DATA = REPO / "tests" / "data" / "cameras"


@pytest.fixture()
def blob_path(tmp_path):
    path = tmp_path / "blob.ply"
    write_ply(blob_scene(), path)
    return path


def lit_fraction(image):
    return float((image.max(axis=2) > 0.02).mean())


def test_render_orbit_writes_one_png_per_view(blob_path, tmp_path, capsys):
    out = tmp_path / "views"
    assert main(["render", str(blob_path), "--orbit", "3", "--size", "64x48", "-o",
                 str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["orbit_000.png", "orbit_001.png",
                                                     "orbit_002.png"]
    for path in out.iterdir():
        image = load_png(path)
        assert image.shape == (48, 64, 3) and 0.05 < lit_fraction(image) < 0.9
    assert "wrote 3 image(s) of 64x48" in capsys.readouterr().out


def test_render_from_camera_file_uses_its_names_and_size(blob_path, tmp_path):
    out = tmp_path / "views"
    assert main(["render", "--quiet", str(blob_path), "--cameras",
                 str(CAMERA_DATA / "inria_cameras.json"), "--size", "80x60", "-o", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["view_a.png", "view_b.png"]
    for name in names:
        image = load_png(out / name)
        assert image.shape == (60, 80, 3) and lit_fraction(image) > 0.05


def test_render_default_is_sixteen_orbit_views(blob_path, tmp_path):
    out = tmp_path / "views"
    assert main(["render", "--quiet", str(blob_path), "--size", "16x12", "-o", str(out)]) == 0
    assert len(list(out.iterdir())) == 16


def test_render_sample_is_centred(tmp_path):
    out = tmp_path / "views"
    assert main(["render", "--quiet", str(SAMPLE), "--orbit", "2", "--size", "120x90", "-o",
                 str(out)]) == 0
    for path in out.iterdir():
        image = load_png(path)
        rows, cols = np.nonzero(image.max(axis=2) > 0.02)
        assert abs(rows.mean() - 45) < 12 and abs(cols.mean() - 60) < 12


def test_render_rejects_cameras_with_orbit(blob_path, tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["render", str(blob_path), "--orbit", "2", "--cameras", "c.json", "-o",
              str(tmp_path)])
    assert info.value.code == 2
    assert "not allowed with" in capsys.readouterr().err


@pytest.mark.parametrize(("options", "message"), [
    (["--size", "64by48"], "size must look like 800x600"),
    (["--size", "0x48"], "size must look like 800x600"),
    (["--orbit", "0"], "1..10,000 views"),
    (["--up", "sideways"], "up axis must be one of"),
    (["--cameras", "missing.json"], "no such file"),
])
def test_render_bad_options_are_one_line_errors(blob_path, tmp_path, capsys, options, message):
    assert main(["render", str(blob_path), *options, "-o", str(tmp_path / "v")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_render_output_that_is_a_file_is_an_error(blob_path, tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert main(["render", str(blob_path), "-o", str(tmp_path / "file")]) == 2
    assert "not a folder" in capsys.readouterr().err


def test_render_rejects_a_damaged_bitstream(tmp_path, capsys):
    (tmp_path / "scene.csgs").write_bytes(b"\x89CSG")
    assert main(["render", str(tmp_path / "scene.csgs"), "-o", str(tmp_path / "v")]) == 2
    err = capsys.readouterr().err
    assert "scene.csgs" in err and "Traceback" not in err
    assert not (tmp_path / "v").exists()


def test_render_rejects_unsupported_scene_type(tmp_path, capsys):
    (tmp_path / "scene.obj").write_bytes(b"v 0 0 0\n")
    assert main(["render", str(tmp_path / "scene.obj"), "-o", str(tmp_path / "v")]) == 2
    assert "'.obj' files are not supported as input to 'csgs render'" in capsys.readouterr().err


def test_render_decodes_a_csgs_bitstream(blob_path, tmp_path, capsys):
    from csgs_codec.codec.encoder import Encoder
    from csgs_codec.interchange.ply_io import read_ply

    bitstream = tmp_path / "blob.csgs"
    bitstream.write_bytes(Encoder(quality=9).encode(read_ply(blob_path)))
    out = tmp_path / "views"
    assert main(["render", str(bitstream), "--orbit", "2", "--size", "64x48", "-o", str(out),
                 "--quiet"]) == 0
    assert len(list(out.glob("*.png"))) == 2


def test_render_quiet_prints_nothing(blob_path, tmp_path, capsys):
    assert main(["render", "--quiet", str(blob_path), "--orbit", "2", "--size", "16x12", "-o",
                 str(tmp_path / "v")]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""


def test_render_shows_progress_unless_quiet(blob_path, tmp_path, capsys):
    assert main(["render", str(blob_path), "--orbit", "2", "--size", "16x12", "-o",
                 str(tmp_path / "v")]) == 0
    assert "rendering" in capsys.readouterr().err
