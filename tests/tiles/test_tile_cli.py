"""``csgs encode --tile-size`` and ``csgs decode --region / --tiles``: output and exit codes."""

from __future__ import annotations

import pytest

from csgs_cli.main import main
from csgs_codec import Decoder
from csgs_codec.interchange.ply_io import read_ply, write_ply
from tests.codec.helpers import random_scene


@pytest.fixture(scope="module")
def tiled_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tiles")
    ply = folder / "scene.ply"
    write_ply(random_scene(2000, seed=2), ply)
    out = folder / "scene.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--tile-size", "500", "--no-hyperprior",
                 "--quiet"]) == 0
    return out


def test_decode_tiles_prints_bytes_read(tiled_file, tmp_path, capsys):
    out = tmp_path / "part.ply"
    capsys.readouterr()
    assert main(["decode", str(tiled_file), "-o", str(out), "--tiles", "3,1", "--quiet"]) == 0
    text = capsys.readouterr().out
    report = Decoder().decode_with_report(tiled_file, tiles=[1, 3])
    assert f"tiles 1,3 of 4; read {report.bytes_read:,} of {tiled_file.stat().st_size:,}" in text
    assert read_ply(out).equals(report.scene)


def test_decode_region(tiled_file, tmp_path, capsys):
    out = tmp_path / "part.ply"
    assert main(["decode", str(tiled_file), "-o", str(out), "--region=-9,-9,-9,9,9,9",
                 "--quiet"]) == 0
    assert "tiles 0-3 of 4" in capsys.readouterr().out
    assert len(read_ply(out)) == 2000


@pytest.mark.parametrize("args", [
    ["--tiles", "7"], ["--tiles", "a,1"], ["--tiles", ""], ["--tiles", "-1"],
    ["--region", "1,2,3"], ["--region", "1,1,1,0,0,0"], ["--region", "a,b,c,d,e,f"],
    ["--region", "1,1,1,2,2,nan"], ["--region", "50,50,50,51,51,51"]])
def test_bad_tiles_and_regions_exit_2(tiled_file, tmp_path, args, capsys):
    out = tmp_path / "never.ply"
    with pytest.raises(SystemExit) as exit_info:
        raise SystemExit(main(["decode", str(tiled_file), "-o", str(out), *args, "--quiet"]))
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and ("tile" in err or "region" in err)
    assert not out.exists()


def test_bad_tile_size_exits_2(tmp_path):
    ply = tmp_path / "s.ply"
    write_ply(random_scene(50), ply)
    with pytest.raises(SystemExit) as exit_info:
        raise SystemExit(main(["encode", str(ply), "-o", str(tmp_path / "s.csgs"),
                               "--tile-size", "0", "--quiet"]))
    assert exit_info.value.code == 2
