"""An ASCII PLY value must fit its property's declared type: an integer property (char,
uchar, short, ushort, int, uint) holds a whole number in the type's range, or the file is an
InputError naming the property and the row (binary files cannot hold such values at all)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.interchange.ply_io import parse_ply_bytes
from tests.scene.ply_samples import property_names

NAMES = property_names(extra=("flags",))
RANGES = {"char": (-128, 127), "uchar": (0, 255), "short": (-32768, 32767),
          "ushort": (0, 65535), "int": (-2**31, 2**31 - 1), "uint": (0, 2**32 - 1),
          "int8": (-128, 127), "uint16": (0, 65535)}
#: Messages name each type by its PLY name (aliases by the name they stand for).
CANONICAL = {"int8": "char", "uint16": "ushort"}


def _ply(ply_type: str, flags: list[str]) -> bytes:
    lines = ["ply", "format ascii 1.0", f"element vertex {len(flags)}"]
    lines += [f"property {ply_type if name == 'flags' else 'float'} {name}" for name in NAMES]
    lines.append("end_header")
    rows = [" ".join(value if name == "flags" else "0.5" for name in NAMES) for value in flags]
    return ("\n".join(lines + rows) + "\n").encode()


def _read(data: bytes):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CsgsWarning)  # 'flags' is dropped, with a warning
        return parse_ply_bytes(data, source="t.ply")


def test_a_uchar_holding_300_is_an_error_naming_row_and_property():
    with pytest.raises(InputError, match=r"vertex row 2: 300 does not fit property type "
                                         r"uchar \(0\.\.255\)") as err:
        _read(_ply("uchar", ["1", "255", "300"]))
    assert (err.value.file, err.value.property, err.value.index) == ("t.ply", "flags", 2)


@pytest.mark.parametrize("ply_type", sorted(RANGES))
def test_each_integer_type_refuses_one_past_each_end(ply_type):
    low, high = RANGES[ply_type]
    for bad in (low - 1, high + 1):
        name = CANONICAL.get(ply_type, ply_type)
        with pytest.raises(InputError, match=f"vertex row 1: {bad} does not fit property "
                                              rf"type {name} \({low}\.\.{high}\)") as err:
            _read(_ply(ply_type, [str(low), str(bad), str(high)]))
        assert (err.value.property, err.value.index) == ("flags", 1)


@pytest.mark.parametrize("ply_type", sorted(RANGES))
def test_each_integer_type_reads_both_ends(ply_type):
    low, high = RANGES[ply_type]
    scene, report = _read(_ply(ply_type, [str(low), str(high), "0"]))
    assert len(scene) == 3 and report.dropped_properties == ["flags"]


@pytest.mark.parametrize("value", ["1.5", "nan", "inf", "-0.25", "1e400"])
def test_an_integer_property_refuses_a_value_that_is_not_a_whole_number(value):
    with pytest.raises(InputError, match=f"vertex row 0: {value} is not a whole number") as err:
        _read(_ply("short", [value, "1"]))
    assert (err.value.property, err.value.index) == ("flags", 0)


def test_whole_numbers_written_with_an_exponent_or_point_still_read():
    scene, _ = _read(_ply("uchar", ["2.0", "1e2", "+7"]))
    assert len(scene) == 3


def test_label_values_keep_their_int_values():
    names = property_names(extra=("label",))
    lines = ["ply", "format ascii 1.0", "element vertex 2"]
    lines += [f"property {'int' if n == 'label' else 'float'} {n}" for n in names]
    lines.append("end_header")
    rows = [" ".join("-2147483648" if n == "label" else "0.5" for n in names),
            " ".join("2147483647" if n == "label" else "0.5" for n in names)]
    scene, _ = parse_ply_bytes(("\n".join(lines + rows) + "\n").encode())
    np.testing.assert_array_equal(scene.labels, [-2**31, 2**31 - 1])
