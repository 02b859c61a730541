"""Small anchor scenes and cached encodes shared by the anchor tests (fast fit settings)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from csgs_codec.codec.anchor_encoder import AnchorEncoder, AnchorEncodeReport
from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.scene.anchor_scene import AnchorScene, MLPWeights
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


def scene_with_origins_and_appearance() -> AnchorScene:
    """80 anchors (F = 24, K = 6) whose file carries view origins (40 given, vorg keeps 32)
    and an appearance table (5 cameras x 4; the color head takes the 4 extra inputs)."""
    scene = synthetic_anchor_scene(2, 40, feat_dim=24, n_offsets=6, seed=4)
    rng = np.random.default_rng(9)
    color = scene.mlps.color
    widened = np.concatenate([color.w1, rng.normal(0, 0.1, (color.w1.shape[0], 4))], axis=1)
    scene.mlps.color = MLPWeights(widened.astype(np.float32), color.b1, color.w2, color.b2)
    scene.mlps.appearance = rng.normal(0, 0.5, (5, 4)).astype(np.float32)
    scene.view_origins = rng.normal(0, 3, (40, 3)).astype(np.float32)
    scene.validate()
    return scene
