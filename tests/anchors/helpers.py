"""Small anchor scenes and cached encodes shared by the anchor tests (fast fit settings)."""

from __future__ import annotations

from functools import lru_cache

from csgs_codec.codec.anchor_encoder import AnchorEncoder, AnchorEncodeReport
from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene

#: Enough training to make the networks non-trivial, little enough for the default suite.
FAST_FIT = FitSettings(steps=40, batch=512)


@lru_cache(maxsize=4)
def small_scene(anchors_per_object: int = 60, masked_fraction: float = 0.2) -> AnchorScene:
    """Five labelled objects, F = 50, K = 10, S = 6, with MLPs."""
    return synthetic_anchor_scene(5, anchors_per_object, masked_fraction=masked_fraction)


@lru_cache(maxsize=8)
def encoded(quality: int = 5, carm_groups: int = 5,
            semantic: str = "auto") -> AnchorEncodeReport:
    """The cached encode of :func:`small_scene`."""
    return AnchorEncoder(quality, carm_groups=carm_groups, semantic=semantic,
                         fit=FAST_FIT).encode_with_report(small_scene())
