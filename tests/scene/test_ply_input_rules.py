"""Nothing in a PLY changes silently (issue #20, items 4 and 5).

Rules: an ASCII row with the wrong number of values is an error naming its row, even when a
long row and a short row add up to the right total; an ASCII value Python reads but PLY does
not ("1_000") is an error naming row and property; a body longer than the header's counts
(rows or bytes after the last element) is an error at the offset where the extra data starts;
a header ends at the first line that is "end_header", so a comment holding the word does not
end it.
"""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import parse_ply_bytes
from tests.scene.ply_samples import make_ply, property_names, random_values

NAMES = property_names()  # 17 properties, SH degree 0


def _ascii_rows(rows: list[list[str]]) -> bytes:
    head = make_ply(np.zeros((0, len(NAMES))), NAMES, fmt="ascii", count=len(rows))
    return head + b"".join(" ".join(r).encode() + b"\n" for r in rows)


def _row(value: float = 0.5) -> list[str]:
    return [repr(value)] * len(NAMES)


def test_an_ascii_row_too_long_then_one_too_short_is_an_error_naming_the_row():
    rows = [_row(), _row() + ["1.0"], _row()[:-1], _row()]
    with pytest.raises(InputError, match="vertex row 1 has 18 values, expected 17") as err:
        parse_ply_bytes(_ascii_rows(rows), source="a.ply")
    assert err.value.index == 1 and err.value.file == "a.ply"


def test_an_ascii_value_with_an_underscore_is_an_error_naming_row_and_property():
    rows = [_row(), _row(), _row()]
    rows[2][NAMES.index("f_dc_1")] = "1_000"
    with pytest.raises(InputError, match="non-numeric value '1_000'") as err:
        parse_ply_bytes(_ascii_rows(rows), source="a.ply")
    assert (err.value.property, err.value.index, err.value.file) == ("f_dc_1", 2, "a.ply")


def test_ascii_nan_inf_and_exponents_still_read():
    rows = [_row(), _row()]
    rows[0][NAMES.index("nx")] = "nan"  # normals are ignored, so NaN there is harmless
    rows[0][NAMES.index("ny")] = "-Infinity"
    rows[1][NAMES.index("f_dc_0")] = "1.5e+2"
    rows[1][NAMES.index("f_dc_1")] = ".25"
    scene, _ = parse_ply_bytes(_ascii_rows(rows))
    assert scene.sh_dc[1, 0] == 150.0 and scene.sh_dc[1, 1] == 0.25


def test_ascii_rows_beyond_the_header_count_are_an_error():
    data = _ascii_rows([_row(), _row(), _row()])
    lying = data.replace(b"element vertex 3", b"element vertex 2")
    with pytest.raises(InputError, match="data follows the last row") as err:
        parse_ply_bytes(lying, source="a.ply")
    assert err.value.offset == len(lying) - len(" ".join(_row())) - 1


def test_binary_bytes_beyond_the_header_count_are_an_error():
    values = random_values(4, NAMES)
    data = make_ply(values, NAMES, count=3)
    with pytest.raises(InputError, match="68 bytes follow the last element") as err:
        parse_ply_bytes(data, source="b.ply")
    assert err.value.offset == len(data) - 68


def test_trailing_garbage_after_a_binary_body_is_an_error():
    data = make_ply(random_values(4, NAMES), NAMES) + b"garbage"
    with pytest.raises(InputError, match="7 bytes follow the last element") as err:
        parse_ply_bytes(data)
    assert err.value.offset == len(data) - 7


def test_an_exact_body_still_reads():
    values = random_values(4, NAMES)
    scene, _ = parse_ply_bytes(make_ply(values, NAMES))
    np.testing.assert_array_equal(scene.sh_dc, values[:, 6:9])
    scene, _ = parse_ply_bytes(make_ply(values, NAMES, fmt="ascii"))
    np.testing.assert_array_equal(scene.sh_dc, values[:, 6:9])


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_a_comment_holding_end_header_does_not_end_the_header(fmt):
    values = random_values(3, NAMES)
    data = make_ply(values, NAMES, fmt=fmt)
    data = data.replace(b"element vertex", b"comment written after end_header tests\n"
                                           b"element vertex", 1)
    scene, _ = parse_ply_bytes(data)
    np.testing.assert_array_equal(scene.opacity, values[:, NAMES.index("opacity")])
