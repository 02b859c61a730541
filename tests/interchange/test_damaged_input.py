"""Damaged files of every interchange format: truncated, bad magic, counts larger than the
file, huge declared sizes. Only typed errors naming the file and where, and no allocation
beyond a small multiple of the file."""

from __future__ import annotations

import gzip
import io
import json
import shutil
import struct
import zipfile

import pytest

from csgs_codec.codec.files import read_scene_with_report
from csgs_codec.errors import CsgsError, InputError
from tests.heap_peak import heap_peak
from tests.interchange.helpers import DATA

FILES = ["brush_sh3.compressed.ply", "brush_sh3.sog", "brush_sh3.v2.spz", "brush_sh3.v3.spz",
         "brush_sh3.v4.spz", "brush_sh3.l0.ksplat", "brush_sh3.l1.ksplat",
         "brush_sh3.l2.ksplat", "brush_sh3.splat", "brush_sh3.glb", "brush_sh3.ply"]


def read_bounded(path):
    """read_scene_with_report(path); returns the CsgsError raised (None if it read), asserting
    the peak of traced allocations stays within 64 bytes per file byte plus 4 MiB."""
    size = path.stat().st_size if path.is_file() else 1 << 16
    try:
        with heap_peak() as peak:
            read_scene_with_report(path)
        return None
    except CsgsError as err:
        return err
    finally:
        assert peak.bytes <= 64 * size + (4 << 20), \
            f"peak {peak.bytes} bytes for a {size}-byte file"


def assert_located(err, path):
    assert err is not None, f"{path} read without error"
    assert err.file is not None and err.file.startswith(str(path)), str(err)
    assert err.offset is not None or err.property is not None, str(err)


@pytest.mark.parametrize("name", FILES)
def test_truncated_files_fail_with_a_located_error(name, tmp_path):
    data = (DATA / name).read_bytes()
    path = tmp_path / name
    for length in sorted({1, 2, 4, 15, 16, 17, 31, 33, 100, 4095, 4097, len(data) // 3,
                          len(data) // 2, len(data) - 7, len(data) - 1} - {0}):
        if length >= len(data):
            continue
        path.write_bytes(data[:length])
        err = read_bounded(path)
        if err is None:
            assert name.endswith(".splat") and length % 32 == 0  # whole records: valid
            continue
        assert_located(err, path)


def test_bad_magic_and_versions(tmp_path):
    cases = {
        "v4.spz": (DATA / "brush_sh3.v4.spz", 4, b"\x05"),  # version 5
        "a.ksplat": (DATA / "brush_sh3.l1.ksplat", 0, b"\x01"),  # major version 1
        "b.ksplat": (DATA / "brush_sh3.l1.ksplat", 20, b"\x07"),  # compression level 7
        "a.glb": (DATA / "brush_sh3.glb", 4, b"\x01"),  # glTF version 1
    }
    for name, (source, offset, patch) in cases.items():
        data = bytearray(source.read_bytes())
        data[offset:offset + len(patch)] = patch
        (tmp_path / name).write_bytes(bytes(data))
        err = read_bounded(tmp_path / name)
        assert isinstance(err, CsgsError) and err.offset is not None, name
    inner = bytearray(gzip.decompress((DATA / "brush_sh3.v3.spz").read_bytes()))
    inner[0:4] = b"XXXX"
    (tmp_path / "magic.spz").write_bytes(gzip.compress(bytes(inner)))
    err = read_bounded(tmp_path / "magic.spz")
    assert isinstance(err, InputError) and "magic" in str(err) and err.offset == 0


def _patched(source, offset, fmt, value):
    data = bytearray(source.read_bytes())
    struct.pack_into(fmt, data, offset, value)
    return bytes(data)


def test_huge_declared_counts_are_refused_before_allocating(tmp_path):
    huge = 2 ** 31 - 1
    cases = {
        "count.spz": _patched(DATA / "brush_sh3.v4.spz", 8, "<I", huge),
        "toc.spz": _patched(DATA / "brush_sh3.v4.spz", 32 + 8, "<Q", 2 ** 60),
        "splats.ksplat": _patched(DATA / "brush_sh3.l1.ksplat", 4096 + 4, "<I", 2 ** 32 - 1),
        "sections.ksplat": _patched(DATA / "brush_sh3.l1.ksplat", 4, "<I", 2 ** 20),
        "buckets.ksplat": _patched(DATA / "brush_sh3.l1.ksplat", 4096 + 12, "<I", 2 ** 30),
    }
    legacy = bytearray(gzip.decompress((DATA / "brush_sh3.v3.spz").read_bytes()))
    struct.pack_into("<I", legacy, 8, huge)
    cases["legacy.spz"] = gzip.compress(bytes(legacy))
    ply = (DATA / "brush_sh3.compressed.ply").read_bytes()
    cases["vertex.compressed.ply"] = ply.replace(b"element vertex 200",
                                                 b"element vertex 2000000000")
    glb = (DATA / "brush_sh3.glb").read_bytes()
    json_length = struct.unpack_from("<I", glb, 12)[0]
    doc = json.loads(glb[20:20 + json_length])
    doc["accessors"][0]["count"] = 10 ** 9
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    rest = glb[20 + json_length:]
    cases["count.glb"] = (struct.pack("<4sII", b"glTF", 2, 20 + len(text) + len(rest))
                          + struct.pack("<II", len(text), 0x4E4F534A) + text + rest)
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        err = read_bounded(tmp_path / name)
        assert isinstance(err, InputError), name
        assert_located(err, tmp_path / name)


def test_sog_with_lying_meta_or_broken_images(tmp_path):
    folder = tmp_path / "sog"
    shutil.copytree(DATA / "donut_sh0_sog", folder)
    meta = json.loads((folder / "meta.json").read_text())
    for change, where in (({"count": 2 ** 26}, "files"), ({"count": -3}, "count"),
                          ({"version": 9}, "version")):
        (folder / "meta.json").write_text(json.dumps({**meta, **change}))
        err = read_bounded(folder)
        assert isinstance(err, CsgsError) and where in (err.property or ""), str(err)
    (folder / "meta.json").write_text(json.dumps({**meta, "means": {**meta["means"],
                                                  "files": ["../escape.webp", "x"]}}))
    assert "plain file name" in str(read_bounded(folder))
    (folder / "meta.json").write_text(json.dumps(meta))
    (folder / "scales.webp").write_bytes(b"RIFF\x00\x00")
    err = read_bounded(folder)
    assert isinstance(err, InputError) and "scales.webp" in str(err)
    (folder / "meta.json").write_text("{not json")
    assert "not JSON" in str(read_bounded(folder))
    # a zip member declaring a huge size
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("meta.json", json.dumps(meta))
    data = bytearray(buffer.getvalue())
    central = data.rfind(b"PK\x01\x02")
    struct.pack_into("<I", data, central + 24, 2 ** 32 - 1)  # uncompressed size
    (tmp_path / "huge.sog").write_bytes(bytes(data))
    err = read_bounded(tmp_path / "huge.sog")
    assert isinstance(err, InputError) and "declares" in str(err)
