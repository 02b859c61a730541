"""The command line never hides a change to the input (issue #20, items 4 and 5).

Rules: one log-scale of 1e15 is refused (exit 2) naming the file, the PLY property and the row
instead of coarsening every other scale; ``--sanitize --quiet`` still says how many Gaussians it
dropped; ``info`` on a file that is neither format says so; ``--layers`` takes the layer names
in any order and shows one choice per layer set; ``layers=''`` in the API is an error, not
"color"; errors name the PLY property ("f_dc_0"), not the attribute ("sh_dc").
"""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec import Decoder, Encoder
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply, write_ply
from tests.codec.helpers import random_scene
from tests.scene.ply_samples import make_ply, property_names, random_values


def test_a_log_scale_of_1e15_is_refused_naming_file_property_and_row(tmp_path, capsys):
    scene = random_scene(50, sh_degree=0)
    scene.scales[7, 1] = 1e15
    src = tmp_path / "huge.ply"
    write_ply(scene, src)
    assert main(["encode", str(src), "-o", str(tmp_path / "o.csgs"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "huge.ply" in err and "property 'scale_1'" in err and "index 7" in err
    assert "log-scale 1e+15 is outside [-88, 88]" in err and "Traceback" not in err
    assert not (tmp_path / "o.csgs").exists()


def test_log_scales_at_the_limit_keep_the_others_precision():
    # One stream holds the three scale channels on one value grid: a value at the limit
    # leaves channels 1 and 2 of every Gaussian exactly as without it.
    encoder = Encoder(quality=5, hyperprior=False)
    plain = encoder.encode_with_report(random_scene(200, sh_degree=0))
    scene = random_scene(200, sh_degree=0)
    scene.scales[0, 0] = 88.0
    edge = encoder.encode_with_report(scene)
    np.testing.assert_array_equal(edge.order, plain.order)
    np.testing.assert_array_equal(edge.reconstruction.scales[:, 1:],
                                  plain.reconstruction.scales[:, 1:])


def test_sanitize_quiet_still_reports_the_dropped_gaussians(tmp_path, capsys):
    names = property_names()
    values = random_values(6, names)
    values[2, names.index("opacity")] = np.nan
    values[4, names.index("x")] = np.inf
    src = tmp_path / "nan.ply"
    src.write_bytes(make_ply(values, names))
    out = tmp_path / "o.csgs"
    assert main(["encode", str(src), "-o", str(out), "--sanitize", "-q"]) == 0
    err = capsys.readouterr().err
    assert "dropped 2 Gaussians with NaN/Inf values" in err
    assert len(Decoder().decode(out)) == 4


def test_info_on_an_all_zero_file_says_it_is_neither_format(tmp_path, capsys):
    zeros = tmp_path / "zero.csgs"
    zeros.write_bytes(bytes(300))
    assert main(["info", str(zeros)]) == 2
    err = capsys.readouterr().err
    assert "zero.csgs" in err and "neither a .csgs bitstream" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("layers", ["semantic,color", "color,semantic", " color , semantic "])
def test_layers_are_taken_in_any_order(tmp_path, capsys, layers):
    src = tmp_path / "s.ply"
    write_ply(random_scene(60, semantic=2), src)
    csgs = tmp_path / "s.csgs"
    assert main(["encode", str(src), "-o", str(csgs), "-q"]) == 0
    out = tmp_path / "d.ply"
    assert main(["decode", str(csgs), "-o", str(out), "--layers", layers, "-q"]) == 0
    assert read_ply(out).semantic.shape == (60, 2)


def test_layers_help_shows_the_choices_once(capsys):
    with pytest.raises(SystemExit):
        main(["decode", "--help"])
    text = capsys.readouterr().out
    assert "color|color,semantic" in text and "{color,color,semantic}" not in text


@pytest.mark.parametrize("bad", ["", "colour", ","])
def test_an_empty_or_unknown_layers_option_is_a_usage_error(tmp_path, capsys, bad):
    with pytest.raises(SystemExit) as exit_info:
        main(["decode", "x.csgs", "-o", str(tmp_path / "o.ply"), "--layers", bad])
    assert exit_info.value.code == 2
    assert "--layers" in capsys.readouterr().err


def test_empty_layers_in_the_api_is_an_error_not_color():
    data = Encoder(hyperprior=False).encode(random_scene(30))
    with pytest.raises(InputError, match="no layer given") as err:
        Decoder().decode(data, layers="")
    assert err.value.property == "layers"


def test_errors_name_the_ply_property_not_the_attribute(tmp_path, capsys):
    names = property_names(sh_rest=9)
    values = random_values(5, names)
    values[3, names.index("f_rest_4")] = np.inf
    src = tmp_path / "inf.ply"
    src.write_bytes(make_ply(values, names))
    assert main(["encode", str(src), "-o", str(tmp_path / "o.csgs"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "property 'f_rest_4'" in err and "index 3" in err and "sh_rest'" not in err
