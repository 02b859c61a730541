"""Encode and decode each stress scene once per quality, shared by the stability tests."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from csgs_codec import Decoder, Encoder
from csgs_codec.codec.encoder import EncodeReport
from csgs_codec.scene.gaussian_scene import GaussianScene
from tests.stability.stress_scenes import STRESS_SCENES


@dataclass(frozen=True)
class RoundTrip:
    """One stress scene through the codec.

    Attributes:
        original: the scene as built (input order).
        reference: ``original`` in the decoder's order (what ``decoded`` approximates).
        result: the encoder's report (bytes, reconstruction, order).
        decoded: ``Decoder().decode(result.data, layers="color,semantic")``.
    """

    original: GaussianScene
    reference: GaussianScene
    result: EncodeReport
    decoded: GaussianScene


def round_trip(scene: GaussianScene, quality: int) -> RoundTrip:
    """Encode ``scene`` at ``quality`` and decode every layer."""
    result = Encoder(quality=quality).encode_with_report(scene)
    decoded = Decoder().decode(result.data, layers="color,semantic")
    return RoundTrip(scene, scene.subset(result.order), result, decoded)


@cache
def stress_round_trip(name: str, quality: int) -> RoundTrip:
    """:func:`round_trip` of the stress scene ``name``, computed once per test session.

    Callers must not modify the arrays.
    """
    return round_trip(STRESS_SCENES[name](), quality)
