"""The CARM refines the feature groups from the decoded ones and saves feature bits."""

from __future__ import annotations

import pytest

from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.anchors.helpers import encoded


def test_carm_writes_one_network_per_group_after_the_first():
    with_carm, without = encoded(carm_groups=5), encoded(carm_groups=1)
    assert with_carm.chunk_bytes["ACRM"] > 100
    assert without.chunk_bytes["ACRM"] == 1  # varint 0: no networks


@pytest.mark.slow
def test_carm_reduces_feature_bits_on_group_correlated_features():
    scene = synthetic_anchor_scene(5, 600)
    fit = FitSettings(steps=150)
    with_carm = AnchorEncoder(5, carm_groups=5, semantic="none", fit=fit).encode_with_report(
        scene)
    without = AnchorEncoder(5, carm_groups=1, semantic="none", fit=fit).encode_with_report(
        scene)
    assert with_carm.chunk_bytes["AFEA"] < 0.97 * without.chunk_bytes["AFEA"]
