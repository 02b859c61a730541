"""Every element of an ASCII PLY, not only the vertices, has exactly the rows its header
count declares, each with the values its properties need (a list: its length, then that many
entries): a missing or short row is an InputError naming the element and row."""

from __future__ import annotations

import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import parse_ply_bytes
from tests.scene.ply_samples import property_names

NAMES = property_names()
VERTEX_ROW = " ".join(["0.5"] * len(NAMES))


def _ply(face_count: int, face_rows: list[str], *, faces_first: bool = False,
         trailing_newline: bool = True) -> bytes:
    vertex = ["element vertex 2"] + [f"property float {n}" for n in NAMES]
    face = [f"element face {face_count}", "property list uchar int vertex_indices",
            "property uchar flag"]
    header = ["ply", "format ascii 1.0", *(face + vertex if faces_first else vertex + face),
              "end_header"]
    body = face_rows + [VERTEX_ROW] * 2 if faces_first else [VERTEX_ROW] * 2 + face_rows
    text = "\n".join(header + body) + ("\n" if trailing_newline else "")
    return text.encode()


def test_two_faces_declared_and_one_present_is_an_error_naming_the_row():
    with pytest.raises(InputError, match="element 'face' declares 2 rows, the body has 1") as e:
        parse_ply_bytes(_ply(2, ["3 0 1 1 7"]), source="f.ply")
    assert (e.value.file, e.value.index) == ("f.ply", 1)


def test_a_missing_last_row_without_a_final_newline_is_an_error_too():
    with pytest.raises(InputError, match="element 'face' declares 2 rows, the body has 1"):
        parse_ply_bytes(_ply(2, ["3 0 1 1 7"], trailing_newline=False), source="f.ply")


def test_complete_face_rows_read_with_or_without_a_final_newline():
    for newline in (True, False):
        scene, _ = parse_ply_bytes(_ply(2, ["3 0 1 1 7", "4 0 1 1 0 2"],
                                        trailing_newline=newline))
        assert len(scene) == 2


@pytest.mark.parametrize("row, message", [
    ("3 0 1 7", "face row 1 has 4 values, its properties need 5"),
    ("3 0 1 1 7 9", "face row 1 has 6 values, its properties need 5"),
    ("x 0 1 1 7", "face row 1: list length 'x' of property 'vertex_indices' is not a count"),
    ("-1 7", "face row 1: list length '-1' of property 'vertex_indices' is not a count"),
    ("", "face row 1 has 0 values"),
])
def test_a_face_row_with_the_wrong_values_is_an_error_naming_it(row, message):
    rows = ["3 0 1 1 7", row, "3 0 1 1 7"]
    with pytest.raises(InputError, match=message) as err:
        parse_ply_bytes(_ply(3, rows), source="f.ply")
    assert err.value.index == 1


def test_a_short_element_before_the_vertices_is_an_error():
    # One face row short: the body holds one row fewer than the counts add up to.
    with pytest.raises(InputError, match="element 'vertex' declares 2 rows, the body has 1"):
        parse_ply_bytes(_ply(2, ["3 0 1 1 7"], faces_first=True), source="f.ply")


def test_a_vertex_row_read_as_a_face_is_an_error_naming_the_face_row():
    rows = ["3 0 1 1 7", VERTEX_ROW.replace("0.5", "1", 1)]
    data = _ply(2, rows, faces_first=True).replace(b"element face 2", b"element face 3")
    data = data.replace(b"end_header\n", b"end_header\n3 0 1 2 7\n")
    with pytest.raises(InputError, match="face row 2 has 17 values, its properties need 3"):
        parse_ply_bytes(data, source="f.ply")
