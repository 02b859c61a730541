"""The Python API answers an argument of the wrong type with an InputError saying what type
was expected (issue #52, item 12), not the AttributeError of its first attribute access."""

from __future__ import annotations

import pytest

from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import InputError, require_type
from csgs_codec.interchange.ply_writer import write_ply
from csgs_codec.interchange.writers import write_scene
from csgs_codec.train.segment import segment_scene
from tests.codec.helpers import random_scene


@pytest.mark.parametrize("given, words", [(None, "got None"),
                                          ("x.ply", "got a str (read a file with"),
                                          (b"ply\n", "got a bytes (read a file with"),
                                          (3, "got an int")])
def test_encode_names_the_expected_type(given, words):
    with pytest.raises(InputError, match="expected a GaussianScene") as err:
        Encoder().encode(given)
    assert words in str(err.value) and err.value.property == "scene"


@pytest.mark.parametrize("writer, suffix", [(write_scene, ".spz"), (write_scene, ".ply"),
                                            (write_ply, ".ply")])
def test_writers_name_the_expected_type(tmp_path, writer, suffix):
    with pytest.raises(InputError, match="expected a GaussianScene, got None"):
        writer(None, tmp_path / f"out{suffix}")
    assert not (tmp_path / f"out{suffix}").exists()


@pytest.mark.parametrize("views, words", [([1], "expected a TrainingView, got an int"),
                                          ("views", "a list of at least one view")])
def test_segment_scene_names_the_expected_views(views, words):
    with pytest.raises(InputError, match=words) as err:
        segment_scene(random_scene(8, sh_degree=0), views)
    assert err.value.property == "views"


def test_require_type_passes_the_right_type_and_lists_alternatives():
    require_type(3, int, "n")
    with pytest.raises(InputError, match="expected an int or float, got a str"):
        require_type("3", (int, float), "n")
