"""Qualities 10-12: the near-lossless end of the presets (standard scenes only)."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions.presets import ANCHOR_QUALITIES, PRESETS, QUALITIES
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.metrics.image import psnr
from csgs_codec.render.rasterizer import render
from tests.conftest import REPO
from tests.render.test_raster_common import orbit_view


def test_the_ladder_goes_on_past_nine_with_finer_steps_and_more_position_bits():
    assert tuple(range(1, 13)) == QUALITIES and tuple(range(1, 10)) == ANCHOR_QUALITIES
    for finer, coarser in zip(QUALITIES[1:], QUALITIES):
        assert PRESETS[finer].rest_step < PRESETS[coarser].rest_step
        assert PRESETS[finer].position_bits >= PRESETS[coarser].position_bits


@pytest.fixture(scope="module")
def donut_head():
    scene = read_ply(REPO / "samples" / "donut.ply")
    return scene.subset(np.arange(min(len(scene), 6000)))


def test_near_lossless_qualities_decode_exactly_and_keep_raising_fidelity(donut_head):
    cameras = [orbit_view(donut_head, np.array([0.0, 0.0, 1.0]), 160, 120, azimuth_deg=a)
               for a in (0.0, 120.0, 240.0)]
    references = [render(donut_head, c).image for c in cameras]
    scores, sizes = [], []
    for quality in (9, 10, 11, 12):
        result = Encoder(quality=quality, hyperprior=False).encode_with_report(donut_head)
        decoded = Decoder().decode(result.data)
        assert decoded.equals(result.reconstruction), quality
        scores.append(np.mean([psnr(render(decoded, c).image, ref)
                               for c, ref in zip(cameras, references)]))
        sizes.append(len(result.data))
    assert scores[0] + 5 < scores[1] and scores[1] + 4 < scores[2], scores
    assert scores[2] + 2 < scores[3], scores
    assert sizes[0] < sizes[1] < sizes[2] < sizes[3]


def test_anchor_scenes_refuse_the_near_lossless_qualities():
    with pytest.raises(InputError, match="anchor scenes take quality 1..9"):
        AnchorEncoder(quality=10)
