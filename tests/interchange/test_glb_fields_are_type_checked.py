"""Every glTF field a GLB reader uses is checked for its JSON type before use: an accessor,
buffer view, offset, count, component type, primitive list, extension list or attribute map
of the wrong type is an InputError naming the field, never a TypeError or ValueError (found
by benchmarks/fuzz_readers.py's JSON edits)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.interchange.gltf import parse_glb

GLB = (Path(__file__).resolve().parents[1] / "data" / "formats" / "brush_sh3.glb").read_bytes()
POSITION = "POSITION"


def _document() -> dict:
    length = struct.unpack_from("<I", GLB, 12)[0]
    return json.loads(GLB[20:20 + length])


def _glb(document: dict) -> bytes:
    length = struct.unpack_from("<I", GLB, 12)[0]
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + GLB[20 + length:]
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _position(doc: dict) -> tuple[dict, dict]:
    """(accessor, buffer view) of POSITION."""
    accessor = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"][POSITION]]
    return accessor, doc["bufferViews"][accessor["bufferView"]]


def _edit(name: str, doc: dict) -> str:
    """Apply edit ``name`` to ``doc``; returns the property the error must name."""
    accessor, view = _position(doc)
    primitive = doc["meshes"][0]["primitives"][0]
    if name == "byteOffset string":
        view["byteOffset"] = "../x.webp"
    elif name == "byteOffset list":
        accessor["byteOffset"] = [[0]]
    elif name == "byteOffset float":
        view["byteOffset"] = 0.5
    elif name == "byteStride negative":
        view["byteStride"] = -12
    elif name == "componentType list":
        accessor["componentType"] = [5126]
    elif name == "count bool":
        accessor["count"] = True
    elif name == "accessor not an object":
        doc["accessors"][primitive["attributes"][POSITION]] = 3
    elif name == "accessor index bool":
        primitive["attributes"][POSITION] = False
    elif name == "bufferView not an object":
        doc["bufferViews"][accessor["bufferView"]] = [0]
    elif name == "bufferView index list":
        accessor["bufferView"] = [0]
    elif name == "buffers not objects":
        doc["buffers"] = [1.5]
    elif name == "view extensions number":
        view["extensions"] = 7
    else:
        raise AssertionError(name)
    return POSITION


EDITS = ["byteOffset string", "byteOffset list", "byteOffset float", "byteStride negative",
         "componentType list", "count bool", "accessor not an object", "accessor index bool",
         "bufferView not an object", "bufferView index list", "buffers not objects"]


@pytest.mark.parametrize("name", EDITS)
def test_a_position_field_of_the_wrong_type_is_an_error_naming_the_attribute(name):
    doc = _document()
    where = _edit(name, doc)
    with pytest.raises(InputError) as err:
        parse_glb(_glb(doc), "t.glb")
    assert err.value.property == where and err.value.file == "t.glb"


def test_buffer_view_extensions_of_any_type_are_unsupported_not_a_crash():
    doc = _document()
    _edit("view extensions number", doc)
    with pytest.raises(UnsupportedError, match=r"compressed buffer views \(7\)") as err:
        parse_glb(_glb(doc), "t.glb")
    assert err.value.property == POSITION


@pytest.mark.parametrize("change, where", [
    (lambda d: d["meshes"][0].__setitem__("primitives", {"a": 1}), "meshes[0]"),
    (lambda d: d["meshes"][0]["primitives"][0].__setitem__("extensions", 5), "meshes"),
    (lambda d: d["meshes"][0]["primitives"][0].__setitem__("attributes", [1]), "attributes"),
    (lambda d: d.__setitem__("extensionsRequired", 3), "extensionsRequired"),
    (lambda d: d.__setitem__("extensionsRequired", [["a"]]), "extensionsRequired"),
    (lambda d: d.__setitem__("accessors", {"0": {}}), "accessors"),
])
def test_a_document_field_of_the_wrong_type_is_an_error_naming_it(change, where):
    doc = _document()
    change(doc)
    with pytest.raises(InputError) as err:
        parse_glb(_glb(doc), "t.glb")
    assert err.value.property == where


def test_the_unedited_document_still_reads():
    scene, _ = parse_glb(_glb(_document()), "t.glb")
    assert len(scene) == 200
