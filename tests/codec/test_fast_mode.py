"""Fast encoder mode: decodes exactly with the normal decoders, costs little size."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions.rate_control import FAST_SEARCH_STEPS, RenderProbe
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.model.anchor_hyperprior import FAST_FIT, FitSettings
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene
from tests.anchors.helpers import small_scene
from tests.conftest import SAMPLE

ANCHOR_FIELDS = ("positions", "features", "offsets", "scaling", "offset_mask", "semantic",
                 "labels")


@pytest.fixture(scope="module")
def fast_anchor_result():
    return AnchorEncoder(fast=True).encode_with_report(small_scene())


@pytest.fixture(scope="module")
def donut_subset():
    scene = read_ply(SAMPLE)
    return scene.subset(np.random.default_rng(1).permutation(len(scene))[:3000])


def test_fast_anchor_encode_decodes_as_reconstructed_by_the_normal_decoder(
        fast_anchor_result):
    decoded = AnchorDecoder().decode(fast_anchor_result.data, layers="color,semantic")
    for name in ANCHOR_FIELDS:
        np.testing.assert_array_equal(getattr(decoded, name),
                                      getattr(fast_anchor_result.reconstruction, name))


def test_fast_anchor_color_layer_alone_decodes_as_reconstructed(fast_anchor_result):
    decoded = AnchorDecoder().decode(fast_anchor_result.data, layers="color")
    np.testing.assert_array_equal(decoded.features, fast_anchor_result.reconstruction.features)
    assert decoded.semantic is None


def test_fast_anchor_mode_fits_with_the_fast_settings():
    assert AnchorEncoder(fast=True).fit == FAST_FIT
    assert FAST_FIT.steps < FitSettings().steps
    assert AnchorEncoder(fast=False).fit == FitSettings()


def test_an_explicit_fit_overrides_fast():
    settings = FitSettings(steps=7)
    assert AnchorEncoder(fast=True, fit=settings).fit is settings


def test_fast_anchor_mode_keeps_the_error_bound(fast_anchor_result):
    scene = small_scene().subset(fast_anchor_result.order)
    error = np.abs(fast_anchor_result.reconstruction.scaling - scene.scaling)
    bound = fast_anchor_result.steps["scaling"][:, None] / 2 + 2.0**-13
    assert np.all(error <= bound + 1e-6)


@pytest.mark.slow
def test_fast_anchor_mode_costs_little_size():
    scene = synthetic_anchor_scene(5, 400, seed=4)
    normal = AnchorEncoder().encode(scene)
    fast = AnchorEncoder(fast=True).encode(scene)
    assert len(fast) <= 1.05 * len(normal)


def test_a_fast_preset_encode_of_a_3dgs_scene_is_the_one_pass_encode(donut_subset):
    fast = Encoder(quality=4, fast=True).encode_with_report(donut_subset)
    assert fast.data == Encoder(quality=4).encode(donut_subset)
    assert Decoder().decode(fast.data).equals(fast.reconstruction)


def test_a_fast_target_psnr_search_tries_fewer_encodes_and_meets_the_target(donut_subset,
                                                                           monkeypatch):
    probe = RenderProbe(donut_subset, views=2, size=(96, 72))
    asked = []
    monkeypatch.setattr("csgs_codec.decisions.rate_control.RenderProbe",
                        lambda scene, **options: asked.append(options) or probe)
    result = Encoder(target_psnr=38.0, fast=True).encode_with_report(donut_subset)
    assert asked == [{}]  # a target is met on the full probe, fast or not
    report = result.rate_control
    assert report.psnr >= 38.0
    assert len(report.trials) <= 2 + FAST_SEARCH_STEPS
    assert Decoder().decode(result.data).equals(result.reconstruction)
