"""The top-level API named in the README works as written."""

from __future__ import annotations

import subprocess
import sys

import csgs_codec
from tests.conftest import fixture


def test_readme_api_round_trip(tmp_path):
    scene = csgs_codec.read_ply(fixture("three_points_sh3.ply"))
    data = csgs_codec.Encoder(quality=9).encode(scene)
    decoded = csgs_codec.Decoder().decode(data, layers="color")
    assert isinstance(decoded, csgs_codec.GaussianScene) and len(decoded) == 3
    result = csgs_codec.encode_file(fixture("three_points_sh3.ply"), tmp_path / "s.csgs",
                                    quality=9)
    assert (tmp_path / "s.csgs").read_bytes() == result.data == data
    assert csgs_codec.decode_file(tmp_path / "s.csgs", tmp_path / "s.ply") == 3
    assert csgs_codec.read_ply(tmp_path / "s.ply").equals(decoded)
    # The Encoder's config or its fields, as Encoder takes them.
    config = csgs_codec.EncoderConfig(quality=9)
    again = csgs_codec.encode_file(fixture("three_points_sh3.ply"), tmp_path / "t.csgs", config)
    assert again.data == data


def test_importing_the_package_and_decoder_loads_no_torch():
    code = ("import sys, csgs_codec; csgs_codec.Decoder; csgs_codec.read_ply; "
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_every_public_name_resolves():
    for name in csgs_codec.__all__:
        assert getattr(csgs_codec, name) is not None, name


def test_anchor_api_round_trip():
    from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene

    scene = synthetic_anchor_scene(n_objects=2, anchors_per_object=40, seed=1)
    result = csgs_codec.AnchorEncoder(quality=5).encode_with_report(scene)
    decoded = csgs_codec.AnchorDecoder().decode(result.data, layers="color,semantic")
    assert isinstance(decoded, csgs_codec.AnchorScene)
    assert decoded.equals(result.reconstruction)
