"""Facts for ``csgs info FILE.csgs --json``."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from csgs_codec.errors import FormatError
from csgs_codec.format import Chunk, describe, format_description, write_container
from tests.format.samples import sample_chunks


def test_describe_lists_version_flags_layers_and_every_chunk():
    data = write_container(sample_chunks())
    facts = describe(data)
    assert (facts["version"], facts["flags"], facts["bytes"]) == ("1.0", 0, len(data))
    assert facts["complete"]
    assert [(c["type"], c["layer"], c["tile"], c["payload_bytes"]) for c in facts["chunks"]] == [
        (c.type, c.layer.label, c.tile, len(c.payload)) for c in sample_chunks()]
    assert all(c["bytes"] == c["payload_bytes"] + 12 for c in facts["chunks"])
    assert {name: layer["chunks"] for name, layer in facts["layers"].items()} == {
        "base": 2, "color": 2, "semantic": 2}
    json.dumps(facts)


def test_describe_byte_counts_add_up_to_the_file_size():
    data = write_container(sample_chunks())
    facts = describe(data)
    layer_bytes = sum(layer["bytes"] for layer in facts["layers"].values())
    assert facts["header_bytes"] + layer_bytes == facts["file_bytes"] == len(data)


def test_describe_marks_critical_and_unknown_chunks():
    facts = describe(write_container([Chunk("fill", 0, b""), Chunk("ABCD", 1, b"x")]))
    assert [(c["critical"], c["known"]) for c in facts["chunks"]] == [(False, True),
                                                                     (True, False)]
    assert "unknown type" in format_description(facts)


def test_describe_with_verify_checks_chunk_crcs():
    data = bytearray(write_container(sample_chunks()))
    data[-1] ^= 0xFF
    assert describe(bytes(data))["complete"]  # header and TOC alone are fine
    with pytest.raises(FormatError, match="CRC"):
        describe(bytes(data), verify=True)


def test_describe_of_a_path_names_the_file(tmp_path):
    target = tmp_path / "scene.csgs"
    write_container(sample_chunks(), path=target)
    facts = describe(target)
    assert facts["file"] == str(target)
    assert str(target) in format_description(facts)


def test_format_package_and_describe_do_not_import_torch(tmp_path):
    target = tmp_path / "scene.csgs"
    write_container(sample_chunks(), path=target)
    code = ("import sys; from csgs_codec.format import describe, read_layers; "
            f"describe({str(target)!r}); read_layers({str(target)!r}); "
            "sys.exit(1 if 'torch' in sys.modules else 0)")
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
