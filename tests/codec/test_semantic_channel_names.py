"""Semantic channel names follow one rule (spec/FORMAT.md §12.16): ``sem_*`` or
``ins_feat_*`` with ASCII letters, digits and underscores, each name once. The encoders
refuse a name that breaks it, naming it; the decoder refuses one in a file at the name's
offset; so a decoded PLY header can neither be ended early nor lose a channel on re-reading
(issue #29, item 1)."""

from __future__ import annotations

import json

import pytest

from csgs_cli.main import main
from csgs_codec import Decoder, Encoder, read_ply
from csgs_codec.chunks.semantic_names import SEMANTIC_NAME
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format.source import open_source
from csgs_codec.format.toc import read_toc
from csgs_codec.semantic.synthetic import labelled_blob_scene
from tests.conftest import REPO

VECTORS = REPO / "spec" / "vectors" / "scenes"
BROKEN = {"semantic_name_duplicate": 1, "semantic_name_newline": 1, "semantic_name_no_prefix": 2}


@pytest.mark.parametrize("names", [
    ("ins_feat_0", "ins_feat_0"), ("", "ins_feat_1"), ("ins_feat_ x", "ins_feat_1"),
    ("ins_feat_a\nend_header", "ins_feat_1"), ("red", "ins_feat_1"), ("ins_feat_", "sem_1"),
    ("sem_é", "sem_1"), ("opacity", "sem_1"),
], ids=["duplicate", "empty", "space", "newline", "no-prefix", "prefix-only", "non-ascii",
        "standard-property"])
def test_the_encoder_refuses_a_name_that_breaks_the_rule(names):
    scene = labelled_blob_scene(2, 50, semantic_dim=2)
    scene.semantic_names = names
    with pytest.raises(InputError) as caught:
        Encoder().encode(scene)
    bad = names[1] if names[0] == names[1] else names[0]
    assert repr(bad) in str(caught.value) or bad in str(caught.value)


def test_names_that_keep_the_rule_survive_a_ply_round_trip(tmp_path):
    scene = labelled_blob_scene(2, 50, semantic_dim=3)
    scene.semantic_names = ("sem_a", "ins_feat_B_2", "sem_3")
    assert all(SEMANTIC_NAME.fullmatch(n) for n in scene.semantic_names)
    data = tmp_path / "s.csgs"
    data.write_bytes(Encoder().encode(scene))
    out = tmp_path / "s.ply"
    assert main(["decode", str(data), "-o", str(out), "--layers", "color,semantic", "-q"]) == 0
    assert read_ply(out).semantic_names == scene.semantic_names


def _name_offset(data: bytes, k: int) -> int:
    """Absolute offset of the length varint of SEMF name ``k`` (names of 1 + 10 bytes)."""
    entry = next(e for e in read_toc(open_source(data)).entries if e.type == "SEMF")
    return entry.offset + 8 + 1 + 11 * k


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_the_decoder_refuses_a_broken_name_at_its_offset(name):
    data = (VECTORS / f"{name}.csgs").read_bytes()
    assert len(Decoder().decode(data, layers="color")) == 40  # the color layer still reads
    with pytest.raises(FormatError) as caught:
        Decoder().decode(data, layers="color,semantic")
    assert (caught.value.chunk, caught.value.offset) == ("SEMF", _name_offset(data, BROKEN[name]))
    record = json.loads((VECTORS / f"{name}.json").read_text())
    assert not record["valid"] and record["reads"][1]["chunk"] == "SEMF"


def test_the_cli_refuses_a_broken_name_with_exit_code_2(tmp_path, capsys):
    out = tmp_path / "out.ply"
    code = main(["decode", str(VECTORS / "semantic_name_newline.csgs"), "-o", str(out),
                 "--layers", "color,semantic", "-q"])
    err = capsys.readouterr().err
    assert code == 2 and "SEMF" in err and "Traceback" not in err
    assert not out.exists()
