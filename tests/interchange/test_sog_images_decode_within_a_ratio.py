"""A SOG image that would decode to more than MAX_RATIO times its file's bytes (a tiny WebP
declaring millions of pixels) is an InputError before it is decoded, and a zip member that
declares more than MAX_RATIO times its compressed size is refused before it is inflated."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.sog import MAX_RATIO, read_sog

FORMATS = Path(__file__).resolve().parents[1] / "data" / "formats"
SIDE = 4096


def _constant_webp(side: int) -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    Image.new("RGBA", (side, side), (1, 2, 3, 4)).save(buffer, "WEBP", lossless=True)
    return buffer.getvalue()


def test_a_tiny_image_of_millions_of_pixels_is_refused_before_decoding(tmp_path):
    pytest.importorskip("PIL")
    folder = tmp_path / "bomb_sog"
    folder.mkdir()
    for member in (FORMATS / "donut_sh0_sog").iterdir():
        (folder / member.name).write_bytes(member.read_bytes())
    meta = json.loads((folder / "meta.json").read_text())
    meta["count"] = SIDE * SIDE // 2
    (folder / "meta.json").write_text(json.dumps(meta))
    bomb = _constant_webp(SIDE)
    assert MAX_RATIO * len(bomb) + (1 << 20) < 4 * SIDE * SIDE
    (folder / "scales.webp").write_bytes(bomb)
    with pytest.raises(InputError, match=f"scales.webp is {SIDE}x{SIDE} pixels in "
                                         f"{len(bomb):,} bytes: more than {MAX_RATIO} times"
                       ) as err:
        read_sog(folder)
    assert err.value.property == "scales.files"


def _lying_zip(data: bytes, declared: int) -> bytes:
    """A zip holding meta.json stored as ``data`` whose headers declare ``declared`` bytes."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        archive.writestr("meta.json", data)
    out = bytearray(buffer.getvalue())
    local, central = out.find(b"PK\x03\x04"), out.find(b"PK\x01\x02")
    out[local + 22:local + 26] = declared.to_bytes(4, "little")
    out[central + 24:central + 28] = declared.to_bytes(4, "little")
    return bytes(out)


def test_a_zip_member_declaring_a_huge_ratio_is_refused(tmp_path):
    path = tmp_path / "lying.sog"
    path.write_bytes(_lying_zip(b"{}", 10 ** 6))
    with pytest.raises(InputError, match="meta.json declares 1,000,000 bytes from 2 compressed"
                       ) as err:
        read_sog(path)
    assert err.value.file == str(path)


def test_a_zip_member_shorter_than_declared_is_refused(tmp_path):
    path = tmp_path / "short.sog"
    path.write_bytes(_lying_zip(b"{}" + b" " * 98, 2000))
    with pytest.raises(InputError, match="meta.json"):
        read_sog(path)
