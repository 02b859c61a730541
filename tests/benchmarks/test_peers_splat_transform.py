"""The splat-transform peers (SOG, compressed PLY, SPZ): wrapper round trips on small scenes.

Tests that run the tool skip when node or the npm package is missing (`npm ci` in
benchmarks/). Bounds are loose multiples of each format's quantization step, tight enough
to catch a scrambled attribute, a wrong matching or a lost SH band.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.peers import (
    SPLAT_TRANSFORM_FORMATS,
    PeerToolError,
    SplatTransformCodec,
    all_peers,
    roundtrip_report,
)
from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.interchange.ply_io import read_ply, write_ply
from tests.conftest import shared_path

FORMATS = sorted(SPLAT_TRANSFORM_FORMATS)


def _codec_or_skip(format: str) -> SplatTransformCodec:
    codec = SplatTransformCodec(format)
    if not codec.available():
        pytest.skip(codec.why_unavailable())
    return codec


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    """name -> (PLY path, scene): 471 Gaussians of donut, and the 3-point SH3 fixture."""
    donut = read_ply(shared_path("scenes", "donut.ply"))
    subset = donut.subset(np.arange(0, len(donut), 97))
    subset_path = tmp_path_factory.mktemp("peers") / "donut_subset.ply"
    write_ply(subset, subset_path)
    three = shared_path("fixtures", "three_points_sh3.ply")
    return {"donut_subset": (subset_path, subset), "three_points_sh3": (three, read_ply(three))}


_round_trips: dict = {}


@pytest.fixture
def round_trip(inputs, tmp_path_factory):
    """(format, input name) -> (EncodeResult, DecodeResult, report), each run once."""

    def run(format: str, name: str):
        key = (format, name)
        if key not in _round_trips:
            codec = _codec_or_skip(format)
            path, scene = inputs[name]
            work = tmp_path_factory.mktemp(f"{format}-{name}")
            encoded = codec.encode(path, work)
            decoded = codec.decode(encoded.path, work / "decoded.ply")
            report = roundtrip_report(scene, read_ply(decoded.path))
            _round_trips[key] = (encoded, decoded, report)
        return _round_trips[key]

    return run


@pytest.mark.parametrize("format", FORMATS)
@pytest.mark.parametrize("name", ["donut_subset", "three_points_sh3"])
def test_round_trip_keeps_every_gaussian(round_trip, format, name):
    _, _, report = round_trip(format, name)
    assert report["dropped_gaussians"] == 0
    assert report["unique_match_fraction"] == 1.0


@pytest.mark.parametrize("format", FORMATS)
@pytest.mark.parametrize("name", ["donut_subset", "three_points_sh3"])
def test_round_trip_values_are_close(round_trip, format, name):
    _, _, report = round_trip(format, name)
    visible = report["visible_only"]
    assert report["position_max_rel_extent"] < 2e-3
    assert visible["color_rms_rgb01"] < 0.01
    assert visible["color_max_rgb01"] < 0.05
    assert visible["opacity_max_alpha"] < 0.01
    assert visible["scale_max_logscale"] < 0.1
    assert visible["rotation_max_deg"] < 3.0


@pytest.mark.parametrize("format", FORMATS)
def test_sh_degree_3_survives_the_round_trip(round_trip, format):
    _, _, report = round_trip(format, "three_points_sh3")
    assert report["sh_degree_out"] == 3
    assert report["sh_rest_rms_coef"] < 0.05
    assert report["sh_rest_max_coef"] < 0.15


@pytest.mark.parametrize("format", FORMATS)
def test_encode_reports_the_file_it_wrote(round_trip, format):
    encoded, decoded, _ = round_trip(format, "donut_subset")
    assert encoded.path.name == "donut_subset" + SPLAT_TRANSFORM_FORMATS[format][1]
    assert encoded.bytes == encoded.path.stat().st_size > 0
    assert encoded.seconds > 0 and decoded.seconds > 0


def test_compressed_ply_infinite_opacities_are_clamped(round_trip):
    _, decoded, _ = round_trip("compressed-ply", "donut_subset")
    assert decoded.fixups.get("opacity_inf_clamped", 0) > 0
    assert np.isfinite(read_ply(decoded.path).opacity).all()


def test_decode_refuses_a_compressed_ply_target(tmp_path):
    codec = _codec_or_skip("sog")
    encoded = tmp_path / "x.sog"
    encoded.write_bytes(b"x")
    with pytest.raises(InputError):
        codec.decode(encoded, tmp_path / "out.compressed.ply")


def test_garbage_input_is_a_peer_tool_error(tmp_path):
    codec = _codec_or_skip("sog")
    garbage = tmp_path / "garbage.sog"
    garbage.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(PeerToolError, match="exited"):
        codec.decode(garbage, tmp_path / "out.ply")
    assert not (tmp_path / "out.ply").exists()


def test_missing_input_is_an_input_error(tmp_path):
    codec = _codec_or_skip("spz")
    with pytest.raises(InputError):
        codec.encode(tmp_path / "absent.ply", tmp_path)


def test_missing_package_says_to_run_npm_ci(tmp_path):
    codec = SplatTransformCodec("sog", node_modules=tmp_path)
    assert not codec.available()
    assert "npm ci" in codec.why_unavailable() or "node" in codec.why_unavailable()
    with pytest.raises(UnsupportedError):
        codec.encode(tmp_path / "absent.ply", tmp_path)


def test_unknown_format_is_an_input_error():
    with pytest.raises(InputError):
        SplatTransformCodec("ksplat")


def test_all_peers_have_distinct_names():
    names = [peer.name for peer in all_peers()]
    assert len(names) == len(set(names))
    assert {"playcanvas-sog", "playcanvas-compressed-ply", "niantic-spz"} <= set(names)
