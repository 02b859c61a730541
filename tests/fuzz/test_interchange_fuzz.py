"""Mutated interchange files (.splat, .ksplat, SPZ v3/v4, compressed PLY, GLB, SOG zip):
only typed csgs errors escape, and no allocation grows beyond a small multiple of the file.

The seeds are the real fixtures in tests/data/formats (a few kilobytes each); mutations
flip bits, overwrite bytes, write large 32-bit values (counts, sizes, offsets) and truncate.
"""

from __future__ import annotations

import gzip
import tempfile
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csgs_codec.errors import CsgsError
from csgs_codec.interchange.compressed_ply import parse_compressed_ply
from csgs_codec.interchange.gltf import parse_glb
from csgs_codec.interchange.ksplat import parse_ksplat
from csgs_codec.interchange.sog import read_sog
from csgs_codec.interchange.splat import parse_splat
from csgs_codec.interchange.spz import parse_spz
from tests.heap_peak import heap_peak

DATA = Path(__file__).resolve().parents[1] / "data" / "formats"


def _sog(data: bytes):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.sog"
        path.write_bytes(data)
        return read_sog(path)


def _spz_inner(data: bytes, source: str):
    """Parse a legacy SPZ whose decompressed payload is ``data`` (mutations inside the gzip
    stream, which its checksum would otherwise catch)."""
    return parse_spz(gzip.compress(data, mtime=0), source)


SEEDS = {
    "splat": ("donut_sh0.splat", parse_splat),
    "ksplat-l1": ("brush_sh3.l1.ksplat", parse_ksplat),
    "ksplat-l2": ("brush_sh3.l2_sh1.ksplat", parse_ksplat),
    "spz-v3": ("brush_sh3.v3.spz", parse_spz),
    "spz-v3-payload": ("brush_sh3.v3.spz", _spz_inner),
    "spz-v4": ("donut_sh0.v4.spz", parse_spz),
    "compressed-ply": ("donut_sh0.compressed.ply", parse_compressed_ply),
    "glb": ("brush_sh3.glb", parse_glb),
    "sog": ("brush_sh3.sog", lambda data, source: _sog(data)),
}


@st.composite
def mutated(draw, base: bytes):
    data = bytearray(base)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "byte", "word"]))
        # Headers and tables sit at the start: aim half the mutations there.
        limit = draw(st.sampled_from([min(len(data), 4200), len(data)])) - 1
        pos = draw(st.integers(0, max(limit, 0)))
        if kind == "flip":
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif kind == "byte":
            data[pos] = draw(st.integers(0, 255))
        else:
            value = draw(st.sampled_from([0, 1, 255, 2 ** 16, 2 ** 31 - 1, 2 ** 32 - 1]))
            data[pos:pos + 4] = value.to_bytes(4, "little")[: len(data) - pos]
    if draw(st.booleans()):
        return bytes(data)
    return bytes(data[: draw(st.integers(len(data) // 2, len(data)))])


def parse_bounded(parse, data: bytes) -> None:
    try:
        with heap_peak() as peak, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            parse(data, "fuzz")
    except CsgsError:
        pass
    assert peak.bytes <= 64 * len(data) + (4 << 20), \
        f"peak {peak.bytes} bytes for {len(data)} bytes"


FAST = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize("kind", sorted(SEEDS))
def test_mutated_files_only_raise_csgs_errors(kind):
    name, parse = SEEDS[kind]
    base = (DATA / name).read_bytes()
    if parse is _spz_inner:
        base = gzip.decompress(base)

    @FAST
    @given(mutated(base))
    def check(data):
        parse_bounded(parse, data)

    check()
