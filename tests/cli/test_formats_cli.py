"""The interchange formats through the command line: encode takes them (warning that a
lossy input compounds loss, even with --quiet), info describes them, decode writes by the
output's extension and refuses an unknown one with exit 2 before decoding."""

from __future__ import annotations

import json

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.files import read_scene_with_report
from tests.interchange.helpers import DATA, matched

INPUTS = {  # fixture -> (format name in info, version, SH degree, lossy)
    "brush_sh3.v4.spz": ("spz", "4", 3, True),
    "brush_sh3.sog": ("sog", "2", 3, True),
    "donut_sh0_sog": ("sog", "2", 0, True),
    "brush_sh3.l2.ksplat": ("ksplat", "0.1", 2, True),
    "brush_sh3.compressed.ply": ("compressed-ply", None, 3, True),
    "donut_sh0.splat": ("splat", None, 0, True),
    "brush_sh3.glb": ("glb", "2.0", 3, False),
    "brush_sh3.ply": ("ply", None, 3, False),
}


@pytest.mark.parametrize("name", sorted(INPUTS))
def test_info_describes_every_format(name, capsys):
    fmt, version, degree, lossy = INPUTS[name]
    assert main(["info", str(DATA / name), "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert (facts["format"], facts["format_version"], facts["lossy"]) == (fmt, version, lossy)
    assert facts["sh_degree_stored"] == degree
    assert facts["gaussians"] == (300 if name.startswith("donut") else 200)
    assert main(["info", str(DATA / name)]) == 0
    first = capsys.readouterr().out.split("\n")[0]
    assert first.startswith(f"{DATA / name}: ") and ("lossy" in first) == lossy


@pytest.mark.parametrize("name", ["brush_sh3.v4.spz", "donut_sh0_sog", "brush_sh3.l2.ksplat",
                                  "brush_sh3.glb"])
def test_encode_takes_the_format_and_warns_when_it_is_lossy(name, tmp_path, capsys):
    out = tmp_path / "scene.csgs"
    assert main(["encode", str(DATA / name), "-o", str(out), "--quality", "9", "-q"]) == 0
    err = capsys.readouterr().err
    assert ("is a lossy format" in err) == INPUTS[name][3]
    original, _ = read_scene_with_report(DATA / name)
    decoded = Decoder().decode(out)
    assert len(decoded) == len(original)
    near = matched(original, decoded)
    extent = float(np.ptp(original.positions, axis=0).max())
    assert np.abs(decoded.positions - near.positions).max() < 1e-3 * extent


@pytest.fixture(scope="module")
def bitstream(tmp_path_factory):
    path = tmp_path_factory.mktemp("decode") / "brush.csgs"
    assert main(["encode", str(DATA / "brush_sh3.ply"), "-o", str(path), "-q"]) == 0
    return path


@pytest.mark.parametrize("suffix,fmt", [(".ply", "ply"), (".glb", "glb"), (".spz", "spz"),
                                        (".splat", "splat")])
def test_decode_writes_the_format_its_extension_names(bitstream, suffix, fmt, tmp_path,
                                                      capsys):
    out = tmp_path / f"out{suffix}"
    assert main(["decode", str(bitstream), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert ("does not carry SH bands" in err) == (suffix == ".splat")
    scene, source = read_scene_with_report(out)
    assert source.format == fmt and len(scene) == 200
    reference = Decoder().decode(bitstream)
    np.testing.assert_allclose(scene.positions, reference.positions, atol=2 ** -12)


def test_decode_to_an_unknown_extension_is_exit_2_and_writes_nothing(bitstream, tmp_path,
                                                                     capsys):
    out = tmp_path / "out.obj"
    assert main(["decode", str(bitstream), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "cannot write '.obj' files" in err and ".glb" in err and "Traceback" not in err
    assert not out.exists()


def test_encode_refuses_a_file_that_is_no_scene(tmp_path, capsys):
    path = tmp_path / "notes.txt"
    path.write_text("hello")
    assert main(["encode", str(path), "-o", str(tmp_path / "x.csgs")]) == 2
    err = capsys.readouterr().err
    assert "notes.txt" in err and "SPZ" in err and not (tmp_path / "x.csgs").exists()
