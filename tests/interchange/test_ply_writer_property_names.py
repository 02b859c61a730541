"""The PLY writer writes only property names a PLY header can hold (issue #52, item 11): a
channel name from the API such as "a\\nelement evil 3" went into the header as lines of its
own, and 'é' failed with UnicodeEncodeError."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.interchange.ply_writer import ply_bytes, vertex_ply_bytes, write_ply
from tests.codec.helpers import random_scene


def _with_channel(name: str):
    scene = random_scene(4, sh_degree=0)
    return dataclasses.replace(scene, semantic=np.arange(4, dtype=np.float32)[:, None],
                               semantic_names=(name,))


@pytest.mark.parametrize("name", ["a\nelement evil 3", "\u00e9", "two words", "", "tab\there",
                                  "x" * 256])
def test_a_name_no_header_can_hold_is_an_input_error(tmp_path, name):
    with pytest.raises(InputError, match="printable ASCII") as err:
        write_ply(_with_channel(name), tmp_path / "out.ply")
    assert repr(name)[:40] in str(err.value)
    assert not (tmp_path / "out.ply").exists()


def test_a_name_given_twice_is_an_input_error():
    with pytest.raises(InputError, match="given twice") as err:
        ply_bytes(_with_channel("opacity"))
    assert err.value.property == "opacity"


def test_a_multi_line_comment_is_an_input_error():
    with pytest.raises(InputError, match="one line"):
        vertex_ply_bytes(1, [("x", np.zeros(1))], comment="ok\nelement evil 3")


def test_a_plain_name_round_trips(tmp_path):
    write_ply(_with_channel("ins_feat_0"), tmp_path / "ok.ply")
    back = read_ply(tmp_path / "ok.ply")
    assert back.semantic_names == ("ins_feat_0",)
    np.testing.assert_array_equal(back.semantic[:, 0], np.arange(4, dtype=np.float32))
