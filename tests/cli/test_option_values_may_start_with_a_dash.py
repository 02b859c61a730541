"""An option's value may start with '-' (issue #29, item 12).

Rules: ``--region -1,-1,-1,1,1,1`` works as ``--region=-1,-1,-1,1,1,1`` does, and so does
every option that takes one value (``--up -z``, ``--click -1,5``, ``--select -3,4``,
``--threshold -0.5``, an abbreviation such as ``--reg``); a word that is itself one of the
command's options is still no value (``-o -q`` is a missing output: exit 2), and nothing after
``--`` is touched.
"""

from __future__ import annotations

import pytest

from csgs_cli.main import attach_dash_values, build_parser, main
from csgs_codec.codec.encoder import Encoder
from tests.codec.helpers import random_scene

BOX = "-0.1,-0.1,-0.1,0.1,0.1,0.1"


@pytest.fixture(scope="module")
def tiled(tmp_path_factory):
    path = tmp_path_factory.mktemp("dash") / "tiled.csgs"
    path.write_bytes(Encoder(quality=4, hyperprior=False, tile_size=100).encode(
        random_scene(400, sh_degree=0)))
    return path


@pytest.mark.parametrize("spelling", [["--region", BOX], [f"--region={BOX}"],
                                      ["--reg", BOX]], ids=["space", "equals", "abbreviated"])
def test_decode_region_with_a_negative_first_number(tiled, tmp_path, capsys, spelling):
    out = tmp_path / "part.ply"
    assert main(["decode", str(tiled), "-o", str(out), *spelling, "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and out.exists()
    assert "tiles " in captured.out


@pytest.mark.parametrize(("argv", "name", "value"), [
    (["render", "s.ply", "--up", "-z", "-o", "d"], "up", "-z"),
    (["select", "s.ply", "--view", "orbit:0", "--click", "-1,5", "-o", "x.ply"], "click",
     "-1,5"),
    (["select", "s.ply", "--view", "orbit:0", "--click", "1,5", "--threshold", "-0.5",
      "-o", "x.ply"], "threshold", -0.5),
    (["view", "s.ply", "--select", "-3,4"], "select", "-3,4"),
    (["-q", "decode", "f.csgs", "-o", "-x.ply"], "output", "-x.ply"),
])
def test_one_value_options_take_a_dash_value(argv, name, value):
    parser = build_parser()
    assert getattr(parser.parse_args(attach_dash_values(parser, argv)), name) == value


def test_region_value_parses_to_six_numbers():
    parser = build_parser()
    args = parser.parse_args(attach_dash_values(parser, ["decode", "f", "-o", "o.ply",
                                                         "--region", BOX]))
    assert args.region == (-0.1, -0.1, -0.1, 0.1, 0.1, 0.1)


def test_an_option_word_is_never_taken_as_a_value(capsys):
    parser = build_parser()
    assert attach_dash_values(parser, ["decode", "f", "-o", "-q"]) == ["decode", "f", "-o", "-q"]
    assert attach_dash_values(parser, ["decode", "f", "--region", "--", "-x"]) == [
        "decode", "f", "--region", "--", "-x"]
    with pytest.raises(SystemExit) as info:
        main(["decode", "f.csgs", "-o", "-q"])
    assert info.value.code == 2
    assert "expected one argument" in capsys.readouterr().err


def test_words_without_a_command_are_left_alone():
    parser = build_parser()
    assert attach_dash_values(parser, ["-q"]) == ["-q"]
    assert attach_dash_values(parser, ["nosuch", "--x", "-1"]) == ["nosuch", "--x", "-1"]
