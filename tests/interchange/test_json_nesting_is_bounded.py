"""JSON read from input files (a GLB's JSON chunk, a SOG meta.json, a cameras JSON file) that
nests too deep, or is not JSON, is an InputError naming the file: never a RecursionError."""

from __future__ import annotations

import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.gltf import BIN_CHUNK, JSON_CHUNK, parse_glb
from csgs_codec.interchange.sog import read_sog
from csgs_codec.scene.cameras_io import load_cameras
from csgs_codec.untrusted import MAX_JSON_DEPTH, load_json

REPO = Path(__file__).resolve().parents[2]
DEEP = b"[" * 100_000
#: Parses without a RecursionError but nests past MAX_JSON_DEPTH.
DEEPISH = b"[" * (MAX_JSON_DEPTH + 1) + b"]" * (MAX_JSON_DEPTH + 1)


def _glb(json_chunk: bytes) -> bytes:
    json_chunk += b" " * (-len(json_chunk) % 4)
    body = struct.pack("<II", len(json_chunk), JSON_CHUNK) + json_chunk
    body += struct.pack("<II", 4, BIN_CHUNK) + b"\0" * 4
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


@pytest.mark.parametrize("text", [DEEP, DEEPISH, b'{"a": ' * 5000 + b"1" + b"}" * 5000],
                         ids=["unclosed", "closed", "objects"])
def test_deep_json_chunk_in_a_glb_is_an_input_error(text):
    with pytest.raises(InputError, match="nests arrays or objects more than 64 levels") as info:
        parse_glb(_glb(text), "deep.glb")
    assert info.value.file == "deep.glb"
    assert info.value.offset == 20


@pytest.mark.parametrize("text", [DEEP, DEEPISH])
def test_deep_sog_meta_json_is_an_input_error(tmp_path, text):
    folder = tmp_path / "deep_sog"
    folder.mkdir()
    (folder / "meta.json").write_bytes(text)
    with pytest.raises(InputError, match="meta.json nests") as info:
        read_sog(folder)
    assert info.value.file == str(folder)
    archive = tmp_path / "deep.sog"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("meta.json", text)
    with pytest.raises(InputError, match="meta.json nests") as info:
        read_sog(archive)
    assert info.value.file == str(archive)


@pytest.mark.parametrize("text", [DEEP, DEEPISH, b'{"frames": ' + DEEP])
def test_deep_cameras_json_is_an_input_error(tmp_path, text):
    path = tmp_path / "cameras.json"
    path.write_bytes(text)
    with pytest.raises(InputError, match="nests arrays or objects") as info:
        load_cameras(path)
    assert info.value.file == str(path)


def test_load_json_names_line_and_column_of_a_syntax_error():
    with pytest.raises(InputError, match=r"x.json: meta.json is not JSON: Expecting "
                                         r"value at line 2 column 3"):
        load_json(b'[1,\n  ]', file="x.json", what="meta.json")


def test_load_json_refuses_bad_utf8_and_huge_integers():
    with pytest.raises(InputError, match="not UTF-8 text"):
        load_json(b'["\xff"]', file="x.json")
    with pytest.raises(InputError, match="is not JSON"):
        load_json(b"[" + b"9" * 5000 + b"]", file="x.json")


def test_load_json_keeps_depth_at_the_limit():
    text = b"[" * MAX_JSON_DEPTH + b"1" + b"]" * MAX_JSON_DEPTH
    document = load_json(text)
    for _ in range(MAX_JSON_DEPTH - 1):
        document = document[0]
    assert document == [1]


def test_cli_info_on_a_deep_glb_exits_2_with_one_line(tmp_path):
    path = tmp_path / "deep.glb"
    path.write_bytes(_glb(DEEP))
    done = subprocess.run([sys.executable, "-m", "csgs_cli.main", "info", str(path)],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines() == [
        f"csgs: error: {path}: byte 20: the JSON chunk nests arrays or objects more than "
        f"{MAX_JSON_DEPTH} levels deep"]
