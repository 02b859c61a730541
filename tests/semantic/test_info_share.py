"""`csgs info` on a .csgs reports the semantic layer's share of the file, text and JSON."""

from __future__ import annotations

import json

import pytest

from csgs_cli.main import main
from csgs_codec.codec.describe import describe_bitstream
from csgs_codec.codec.encoder import Encoder
from csgs_codec.semantic.synthetic import labelled_blob_scene


@pytest.fixture(scope="module")
def encoded(tmp_path_factory):
    scene = labelled_blob_scene(3, 200, seed=4)
    folder = tmp_path_factory.mktemp("info")
    with_layer, without = folder / "with.csgs", folder / "without.csgs"
    with_layer.write_bytes(Encoder(quality=5).encode(scene))
    without.write_bytes(Encoder(quality=5, semantic="none").encode(scene))
    return with_layer, without


def test_semantic_share_is_semantic_bytes_over_file_bytes(encoded):
    facts = describe_bitstream(encoded[0])
    expected = 100.0 * facts["layers"]["semantic"]["bytes"] / facts["file_bytes"]
    assert facts["semantic_share_percent"] == pytest.approx(expected)
    assert 0 < facts["semantic_share_percent"] < 100


def test_semantic_share_is_zero_without_a_semantic_layer(encoded):
    assert describe_bitstream(encoded[1])["semantic_share_percent"] == 0.0


def test_info_json_and_text_show_the_semantic_share(encoded, capsys):
    assert main(["info", "--json", str(encoded[0])]) == 0
    share = json.loads(capsys.readouterr().out)["semantic_share_percent"]
    assert main(["info", str(encoded[0])]) == 0
    lines = capsys.readouterr().out.splitlines()
    share_line = next(i for i, line in enumerate(lines) if "semantic share" in line)
    assert f"{share:.2f}% of the file" in lines[share_line]
    assert lines[share_line - 1].startswith("  semantic ")  # right under the layer's bytes
