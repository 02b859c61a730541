"""A vertex element without properties is an InputError naming the element, whatever count
it declares (found by benchmarks/fuzz_readers.py: a count of 2^64 with no properties took no
bytes and overflowed numpy's row count); elements without properties elsewhere hold nothing
and are skipped."""

from __future__ import annotations

import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.compressed_ply import parse_compressed_ply
from csgs_codec.interchange.ply_io import parse_ply_bytes, read_ply
from csgs_codec.interchange.ply_mmap import MappedPly
from tests.scene.ply_samples import make_ply, property_names, random_values

NAMES = property_names()


def _empty_vertex(count: int, fmt: str = "binary_little_endian") -> bytes:
    """A PLY whose vertex element has no properties; the properties follow in 'chunk'."""
    data = make_ply(random_values(2, NAMES), NAMES, fmt=fmt)
    return data.replace(b"element vertex 2\n", f"element vertex {count}\nelement chunk 2\n"
                        .encode())


@pytest.mark.parametrize("count", [0, 3, 2 ** 64])
@pytest.mark.parametrize("fmt", ["binary_little_endian", "ascii"])
def test_a_vertex_element_without_properties_is_an_input_error(count, fmt):
    with pytest.raises(InputError, match="element 'vertex' has no properties") as err:
        parse_ply_bytes(_empty_vertex(count, fmt), source="e.ply")
    assert err.value.file == "e.ply"


def test_a_mapped_vertex_element_without_properties_is_an_input_error(tmp_path):
    path = tmp_path / "e.ply"
    path.write_bytes(_empty_vertex(2 ** 64))
    with pytest.raises(InputError, match="element 'vertex' has no properties"):
        MappedPly(path)
    with pytest.raises(InputError, match="element 'vertex' has no properties"):
        read_ply(path)


def test_an_element_without_properties_before_the_vertices_is_skipped():
    data = make_ply(random_values(2, NAMES), NAMES)
    data = data.replace(b"element vertex 2\n", b"element empty 1000000\nelement vertex 2\n")
    scene, _ = parse_ply_bytes(data)
    assert len(scene) == 2


def test_a_compressed_ply_element_without_properties_is_an_input_error():
    header = (b"ply\nformat binary_little_endian 1.0\nelement chunk 18446744073709551616\n"
              b"element vertex 1\nproperty uint packed_position\nend_header\n")
    with pytest.raises(InputError, match="element 'chunk' has no properties"):
        parse_compressed_ply(header + b"\0" * 4, "c.ply")
