"""The Draco peer: point cloud plus uniformly quantized 3DGS attributes, and its file checks."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.peers import DracoCodec, PeerToolError, roundtrip_report
from benchmarks.peers.draco import decode_scene
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply, write_ply
from tests.conftest import shared_path

pytest.importorskip("DracoPy")


@pytest.fixture(scope="module")
def donut_subset(tmp_path_factory):
    donut = read_ply(shared_path("scenes", "donut.ply"))
    scene = donut.subset(np.arange(0, len(donut), 97))
    path = tmp_path_factory.mktemp("draco") / "donut_subset.ply"
    write_ply(scene, path)
    return path, scene


def _round_trip(codec, path, scene, tmp_path):
    encoded = codec.encode(path, tmp_path)
    decoded = codec.decode(encoded.path, tmp_path / "decoded.ply")
    return encoded, roundtrip_report(scene, read_ply(decoded.path))


def test_round_trip_keeps_every_gaussian_with_close_values(donut_subset, tmp_path):
    encoded, report = _round_trip(DracoCodec(), *donut_subset, tmp_path)
    assert encoded.bytes == encoded.path.stat().st_size
    assert report["dropped_gaussians"] == 0
    assert report["unique_match_fraction"] == 1.0
    assert report["position_max_rel_extent"] < 1e-4
    assert report["color_max_rgb01"] < 0.02
    assert report["opacity_max_alpha"] < 0.02
    assert report["rotation_max_deg"] < 2.0


def test_sh_degree_3_survives_the_round_trip(tmp_path):
    path = shared_path("fixtures", "three_points_sh3.ply")
    _, report = _round_trip(DracoCodec(), path, read_ply(path), tmp_path)
    assert report["sh_degree_out"] == 3
    assert report["sh_rest_max_coef"] < 0.01


def test_more_attribute_bits_give_smaller_errors(donut_subset, tmp_path):
    _, coarse = _round_trip(DracoCodec(attribute_bits=6), *donut_subset, tmp_path / "6")
    _, fine = _round_trip(DracoCodec(attribute_bits=12), *donut_subset, tmp_path / "12")
    assert fine["color_rms_rgb01"] < coarse["color_rms_rgb01"] / 10
    assert fine["scale_rms_logscale"] < coarse["scale_rms_logscale"] / 10


def test_wrong_magic_is_an_input_error(donut_subset):
    data = bytearray(DracoCodec().encode_scene(donut_subset[1]))
    data[:4] = b"XXXX"
    with pytest.raises(InputError):
        decode_scene(bytes(data))


def test_truncated_ranges_are_an_input_error(donut_subset):
    data = DracoCodec().encode_scene(donut_subset[1])
    with pytest.raises(InputError):
        decode_scene(data[:20])


def test_corrupt_draco_buffer_is_a_peer_tool_error(donut_subset):
    data = DracoCodec().encode_scene(donut_subset[1])
    header_and_ranges = 10 + 8 * 11
    with pytest.raises((PeerToolError, InputError)):
        decode_scene(data[:header_and_ranges] + b"\x00" * 64)


def test_settings_out_of_range_are_an_input_error():
    with pytest.raises(InputError):
        DracoCodec(attribute_bits=17)
