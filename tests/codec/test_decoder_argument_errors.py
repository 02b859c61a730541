"""A careless decode argument is an InputError naming it (issue #29, items 7 and 15).

Rules: ``tiles=[]`` (no tile at all) is refused, as the CLI refuses an empty ``--tiles``, never
answered with a None scene; ``layers`` must be a string of layer names or a list of them, and
anything else (None, a number, bytes, a list holding a non-string) is an InputError naming the
accepted values, in the 3DGS and the anchor decoder alike; ``decode`` never returns None.
"""

from __future__ import annotations

import pytest

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import InputError
from tests.anchors.helpers import encoded
from tests.codec.helpers import random_scene

SCENE = random_scene(400, sh_degree=0)
DATA = Encoder(quality=4, hyperprior=False).encode(SCENE)
TILED = Encoder(quality=4, hyperprior=False, tile_size=100).encode(SCENE)
BAD_LAYERS = [None, 5, 1.5, b"color", ["color", 5], [None], {"color": 1}, range(2)]


@pytest.mark.parametrize("data", [DATA, TILED], ids=["untiled", "tiled"])
@pytest.mark.parametrize("tiles", [[], (), set()])
def test_an_empty_tile_list_is_an_input_error(data, tiles):
    with pytest.raises(InputError, match="no tile") as info:
        Decoder().decode(data, tiles=tiles)
    assert info.value.property == "tiles"
    with pytest.raises(InputError, match="no tile"):
        Decoder().decode_with_report(data, tiles=tiles)


def test_a_path_and_an_empty_tile_list(tmp_path):
    path = tmp_path / "scene.csgs"
    path.write_bytes(TILED)
    with pytest.raises(InputError, match="no tile"):
        Decoder().decode(path, tiles=[])


def test_decode_of_a_region_meeting_no_tile_raises_not_none():
    with pytest.raises(InputError, match="no tile meets the region"):
        Decoder().decode(TILED, region=(5, 5, 5, 6, 6, 6))
    report = Decoder().decode_with_report(TILED, region=(5, 5, 5, 6, 6, 6))
    assert report.tiles == [] and report.scene is None  # the report says so, no error


@pytest.mark.parametrize("layers", BAD_LAYERS, ids=repr)
def test_a_layers_argument_of_the_wrong_type_is_an_input_error(layers):
    with pytest.raises(InputError, match="'color' or 'color,semantic'") as info:
        Decoder().decode(DATA, layers=layers)
    assert info.value.property == "layers"


@pytest.mark.parametrize("layers", BAD_LAYERS, ids=repr)
def test_the_anchor_decoder_refuses_the_same_layers(layers):
    with pytest.raises(InputError, match="'color' or 'color,semantic'"):
        AnchorDecoder().decode(encoded().data, layers=layers)


@pytest.mark.parametrize("layers", ["color", "color,semantic", ["color"], ("semantic", "color"),
                                    {"color"}, frozenset({"color", "semantic"})])
def test_accepted_layers_values_decode(layers):
    assert len(Decoder().decode(DATA, layers=layers)) == len(SCENE)


@pytest.mark.parametrize("layers", ["colour", "", [], ["bogus"]])
def test_unknown_or_no_layer_names_are_input_errors(layers):
    with pytest.raises(InputError) as info:
        Decoder().decode(DATA, layers=layers)
    assert info.value.property == "layers"


def test_layer_enum_members_name_the_same_layers_as_strings():
    from csgs_codec import Layer, decode

    labelled = Encoder(quality=4, hyperprior=False).encode(
        random_scene(300, sh_degree=0, seed=5, labels=True))
    both = Decoder().decode(labelled, layers="color,semantic")
    assert both.labels is not None
    for layers in (Layer.SEMANTIC, [Layer.COLOR, Layer.SEMANTIC], ["color", Layer.SEMANTIC]):
        scene = decode(labelled, layers=layers)
        assert (scene.labels == both.labels).all()
        assert (scene.sh_dc == both.sh_dc).all() and (scene.positions == both.positions).all()
    assert decode(labelled, layers=Layer.COLOR).labels is None
