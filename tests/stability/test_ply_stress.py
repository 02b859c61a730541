"""Stress scenes through the PLY writer and reader: every float32 value survives bit for bit.

Rules: a stress scene (denormals, negative zeros, +-65504, 3e38, N = 0 or 1, unnormalised or
zero quaternions) written as PLY reads back identical to the bit, as does its decoded scene;
half-precision and ASCII PLYs at the float16 and denormal limits read exactly; values a PLY
holds that overflow float32, and labels outside int32, are refused naming the property.
"""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import parse_ply_bytes, ply_bytes, read_ply, write_ply
from tests.scene.ply_samples import make_ply, property_names
from tests.stability.round_trips import stress_round_trip
from tests.stability.stress_scenes import (
    DENORMAL_MAX,
    DENORMAL_MIN,
    FLOAT16_MAX,
    STRESS_SCENES,
    with_semantic,
)

NAMES = property_names()


@pytest.mark.parametrize("name", list(STRESS_SCENES))
def test_stress_scene_ply_round_trip_is_bit_exact(name, tmp_path):
    scene = STRESS_SCENES[name]()
    if scene.semantic is None:
        scene = with_semantic(scene)
    write_ply(scene, tmp_path / "s.ply")
    back = read_ply(tmp_path / "s.ply")
    assert back.equals(scene)


@pytest.mark.parametrize("name", list(STRESS_SCENES))
def test_decoded_stress_scene_ply_round_trip_is_bit_exact(name):
    decoded = stress_round_trip(name, 5).decoded
    back, _ = parse_ply_bytes(ply_bytes(decoded))
    assert back.equals(decoded)


def test_negative_zero_keeps_its_sign_bit():
    scene = STRESS_SCENES["denormals"]()
    assert np.signbit(scene.sh_dc[-2]).all() and not scene.sh_dc[-2].any()
    back, _ = parse_ply_bytes(ply_bytes(scene))
    assert np.signbit(back.sh_dc[-2]).all()


def _one_row(values: dict[str, float]) -> np.ndarray:
    row = np.zeros((1, len(NAMES)), np.float64)
    row[0, NAMES.index("rot_0")] = 1.0
    for name, value in values.items():
        row[0, NAMES.index(name)] = value
    return row


def test_half_precision_properties_at_the_float16_limit_read_exactly():
    row = np.repeat(_one_row({"f_dc_0": FLOAT16_MAX, "f_dc_1": -FLOAT16_MAX,
                              "opacity": FLOAT16_MAX, "scale_0": -FLOAT16_MAX}), 2, axis=0)
    data = make_ply(row, NAMES, types={name: "half" for name in NAMES})
    scene, _ = parse_ply_bytes(data)
    np.testing.assert_array_equal(scene.sh_dc[:, :2], [[65504, -65504]] * 2)
    assert scene.opacity[0] == 65504 and scene.scales[0, 0] == -65504


def test_half_precision_infinity_is_refused_naming_the_property():
    row = _one_row({"scale_1": np.inf})
    data = make_ply(row, NAMES, types={name: "half" for name in NAMES})
    with pytest.raises(InputError) as err:
        parse_ply_bytes(data)
    assert err.value.property == "scale_1" and err.value.index == 0


def test_ascii_denormals_read_exactly():
    row = _one_row({"f_dc_0": float(DENORMAL_MIN), "f_dc_1": float(-DENORMAL_MAX),
                    "x": 1e-40})
    scene, _ = parse_ply_bytes(make_ply(row, NAMES, fmt="ascii"))
    np.testing.assert_array_equal(scene.sh_dc[0, :2], [DENORMAL_MIN, -DENORMAL_MAX])
    assert scene.positions[0, 0] == np.float32(1e-40)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_double_beyond_float32_is_refused_naming_the_property(fmt):
    row = _one_row({"f_dc_2": 1e39})
    data = make_ply(row, NAMES, fmt=fmt, types={"f_dc_2": "double"})
    with pytest.raises(InputError) as err:
        parse_ply_bytes(data)
    assert err.value.property == "f_dc_2" and err.value.index == 0


def test_double_at_the_float32_limit_reads_as_that_limit():
    largest = float(np.finfo(np.float32).max)
    row = _one_row({"x": largest, "y": -largest})
    scene, _ = parse_ply_bytes(make_ply(row, NAMES, types={"x": "double", "y": "double"}))
    assert scene.positions[0, 0] == np.float32(largest)
    assert scene.positions[0, 1] == -np.float32(largest)


def test_empty_scene_ply_keeps_its_sh_degree():
    scene = STRESS_SCENES["n0"]()
    back, _ = parse_ply_bytes(ply_bytes(scene))
    assert len(back) == 0 and back.sh_degree_stored == 3


def test_labels_at_both_int32_limits_round_trip():
    scene = STRESS_SCENES["semantic_extremes"]()
    assert scene.labels.min() == np.iinfo(np.int32).min
    back, _ = parse_ply_bytes(ply_bytes(scene))
    np.testing.assert_array_equal(back.labels, scene.labels)


@pytest.mark.parametrize("label", [2.0**31, -(2.0**31) - 1, 0.5])
def test_label_outside_int32_is_refused_naming_it(label):
    row = np.concatenate([_one_row({}), [[label]]], axis=1)
    data = make_ply(row, [*NAMES, "label"], types={"label": "double"})
    with pytest.raises(InputError) as err:
        parse_ply_bytes(data)
    assert err.value.property == "label" and err.value.index == 0
