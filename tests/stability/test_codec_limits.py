"""Values at the edge of what the color codec can code: refused by name, or round-tripped.

Rules: float attribute values up to 2^52 in magnitude round-trip; a value too large for the
codec's value grid (|value| around 2^53 and beyond; log-scales or SH coefficients no trained
scene has) is refused with an InputError that names the attribute; whatever the encoder
accepts, its decoder decodes; opacity pruning of saturated logits raises no floating-point
warnings; positions, opacity and rotations take any finite float32.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.errors import InputError
from tests.stability.bounds import assert_all_finite
from tests.stability.round_trips import round_trip
from tests.stability.stress_scenes import huge_opacity_logits, plain_scene, with_semantic

#: The PLY property of channel 0 of each attribute (SH degree 1: f_rest_0 is band 0 of red).
FIRST_PLY_PROPERTY = {"sh_dc": "f_dc_0", "sh_rest": "f_rest_0", "scales": "scale_0",
                      "semantic": "ins_feat_0"}


def _scene_with(attribute: str, value: float):
    scene = with_semantic(plain_scene())
    column = getattr(scene, attribute).reshape(len(scene), -1)
    column[5, 0] = value
    column[6, 0] = -value
    return scene


@pytest.mark.parametrize("attribute", ["sh_dc", "sh_rest", "scales", "semantic"])
@pytest.mark.parametrize("value", [1e16, 3e38], ids=["1e16", "3e38"])
def test_values_beyond_the_value_grid_are_refused_naming_the_attribute(attribute, value):
    with pytest.raises(InputError) as err:
        Encoder(quality=5).encode(_scene_with(attribute, value))
    assert err.value.property == FIRST_PLY_PROPERTY[attribute] and err.value.index == 5


# Log-scales are refused beyond +-88 (tests/codec/test_input_rules.py), so not here.
@pytest.mark.parametrize("attribute", ["sh_dc", "sh_rest", "semantic"])
def test_values_up_to_2_to_the_52_round_trip(attribute):
    scene = _scene_with(attribute, 2.0**52)
    trip = round_trip(scene, 1)
    assert trip.decoded.equals(trip.result.reconstruction)
    assert_all_finite(trip.decoded)
    values = getattr(trip.decoded, attribute).reshape(len(scene), -1)[:, 0]
    reference = getattr(trip.reference, attribute).reshape(len(scene), -1)[:, 0]
    big = np.abs(reference) == 2.0**52
    assert big.sum() == 2
    np.testing.assert_allclose(values[big], reference[big], rtol=1e-6)


@pytest.mark.parametrize("attribute", ["positions", "opacity", "rotations"])
def test_attributes_without_a_value_limit_take_the_largest_float32(attribute):
    largest = float(np.finfo(np.float32).max)
    scene = _scene_with(attribute, largest)
    result = Encoder(quality=5).encode_with_report(scene)
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert decoded.equals(result.reconstruction)
    assert_all_finite(decoded)


# Log-scales centre near -4: a mean of that sign plus 2^53 would pass the decoder's limit.
@pytest.mark.parametrize("attribute", ["sh_dc", "sh_rest", "scales", "semantic"])
def test_whatever_the_encoder_accepts_decodes(attribute):
    scene = _scene_with(attribute, 2.0**53)
    try:
        result = Encoder(quality=5).encode_with_report(scene)
    except InputError as err:
        assert err.property == FIRST_PLY_PROPERTY[attribute]
        return
    decoded = Decoder().decode(result.data, layers="color,semantic")
    assert decoded.equals(result.reconstruction)


def test_pruning_saturated_opacity_logits_raises_no_warning():
    scene = huge_opacity_logits()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = Encoder(quality=5, prune_opacity=0.01).encode_with_report(scene)
    assert result.pruned >= np.count_nonzero(scene.opacity == -1e4)
