"""Bad PLY input: each case is an InputError naming the file and the property or offset."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import parse_ply_bytes, read_ply, read_ply_with_report
from tests.scene.ply_samples import make_ply, property_names, random_values

NAMES = property_names()
GOOD = make_ply(random_values(4, NAMES), NAMES)


def assert_input_error(data: bytes, match: str, **context) -> InputError:
    with pytest.raises(InputError, match=match) as info:
        parse_ply_bytes(data, source="scene.ply")
    assert "scene.ply" in str(info.value)
    for key, value in context.items():
        assert getattr(info.value, key) == value
    return info.value


def test_missing_file_names_the_file(tmp_path):
    with pytest.raises(InputError, match="not found") as info:
        read_ply(tmp_path / "nope.ply")
    assert "nope.ply" in str(info.value)


def test_empty_file():
    assert_input_error(b"", "empty file")


def test_non_ply_bytes():
    assert_input_error(b"\x89PNG\r\n\x1a\n" + bytes(100), "not a PLY", offset=0)


def test_truncated_header():
    assert_input_error(GOOD[:40], "truncated header")


def test_truncated_body():
    assert_input_error(GOOD[:-5], "truncated body")


def test_element_count_larger_than_body():
    data = make_ply(random_values(4, NAMES), NAMES, count=10**12)
    err = assert_input_error(data, "declares 1000000000000 rows")
    assert err.offset == data.index(b"end_header\n") + len(b"end_header\n")


def test_ascii_count_larger_than_body():
    data = make_ply(random_values(4, NAMES), NAMES, fmt="ascii", count=10**9)
    assert_input_error(data, "declares 1000000000 rows")


@pytest.mark.parametrize("missing", ["x", "opacity", "rot_3", "f_dc_1", "scale_0"])
def test_missing_required_property_is_named(missing):
    names = [n for n in NAMES if n != missing]
    assert_input_error(make_ply(random_values(2, names), names), "required property missing",
                 property=missing)


@pytest.mark.parametrize("count", [1, 3, 10, 44, 48])
def test_wrong_f_rest_count_names_the_count(count):
    names = property_names(count)
    assert_input_error(make_ply(random_values(2, names), names), f"{count} f_rest properties")


def test_f_rest_with_a_gap_names_the_missing_property():
    names = [n if n != "f_rest_4" else "f_rest_9" for n in property_names(9)]
    assert_input_error(make_ply(random_values(2, names), names), "not numbered",
                       property="f_rest_4")


def test_list_property_is_refused():
    data = GOOD.replace(b"property float rot_3\n",
                        b"property float rot_3\nproperty list uchar int vertex_indices\n")
    assert_input_error(data, "list properties", property="vertex_indices")


def test_bad_format_line():
    assert_input_error(GOOD.replace(b"binary_little_endian", b"binary_middle_endian"),
                 "unsupported format")


def test_non_numeric_ascii_value():
    data = make_ply(random_values(2, NAMES), NAMES, fmt="ascii")
    head, body = data.split(b"end_header\n")
    assert_input_error(head + b"end_header\n" + body.replace(b"0", b"z", 1), "non-numeric")


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_values_are_an_error_naming_property_and_index(bad):
    values = random_values(5, NAMES)
    values[3, NAMES.index("scale_1")] = bad
    assert_input_error(make_ply(values, NAMES), "non-finite", property="scale_1", index=3)


def test_float64_overflowing_float32_is_nonfinite():
    values = random_values(3, NAMES).astype(np.float64)
    values[1, 0] = 1e300
    assert_input_error(make_ply(values, NAMES, types={"x": "double"}), "non-finite",
                 property="x", index=1)


def test_sanitize_drops_nonfinite_gaussians_and_reports_count(tmp_path):
    values = random_values(6, NAMES)
    values[1, NAMES.index("opacity")] = np.nan
    values[4, NAMES.index("rot_2")] = np.inf
    path = tmp_path / "s.ply"
    path.write_bytes(make_ply(values, NAMES))
    with pytest.warns(UserWarning, match="dropped 2 Gaussians"):
        scene, report = read_ply_with_report(path, sanitize=True)
    assert len(scene) == 4 and report.nonfinite_dropped == 2
    np.testing.assert_array_equal(scene.positions[:, 0], values[[0, 2, 3, 5], 0])


def test_non_integer_label_is_refused():
    names = property_names(extra=("label",))
    values = random_values(3, names)
    values[:, -1] = [0, 1, 1.5]
    assert_input_error(make_ply(values, names), "not a 32-bit integer", property="label", index=2)


def test_directory_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="directory"):
        read_ply(tmp_path)
