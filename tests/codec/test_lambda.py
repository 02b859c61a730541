"""--lambda: the rate-distortion weight instead of a preset (standard and anchor scenes)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions.rate_control import (
    FAST_LAMBDA_STEPS,
    FAST_PROBE_VIEWS,
    LambdaReport,
    RenderProbe,
)
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.model.anchor_hyperprior import step_for_lambda
from tests.anchors.helpers import FAST_FIT, small_scene
from tests.conftest import SAMPLE

BAD_LAMBDAS = [0.0, -1.0, float("nan"), float("inf"), "big"]


@pytest.fixture(scope="module")
def donut_subset():
    scene = read_ply(SAMPLE)
    return scene.subset(np.random.default_rng(0).permutation(len(scene))[:3000])


@pytest.fixture(scope="module")
def probe(donut_subset):
    return RenderProbe(donut_subset, views=2, size=(96, 72))


@pytest.fixture(scope="module")
def lambda_run(donut_subset, probe):
    """Fast lambda encodes of the donut subset at three weights: ({lambda: (result,
    report)}, the options each encode asked RenderProbe for)."""
    results, asked = {}, []
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("csgs_codec.decisions.rate_control.RenderProbe",
                      lambda scene, **options: asked.append(options) or probe)
        for lam in (0.02, 0.4, 8.0):
            result = Encoder(lambda_=lam, fast=True).encode_with_report(donut_subset)
            results[lam] = (result, result.rate_control)
    return results, asked


@pytest.fixture(scope="module")
def lambda_encodes(lambda_run):
    return lambda_run[0]


def test_a_larger_lambda_gives_a_smaller_file(lambda_encodes):
    sizes = [len(lambda_encodes[lam][0].data) for lam in sorted(lambda_encodes)]
    assert sizes[0] > sizes[1] > sizes[2]


def test_the_kept_encode_has_the_least_cost_of_the_trials(lambda_encodes, donut_subset):
    for lam, (result, report) in lambda_encodes.items():
        assert isinstance(report, LambdaReport) and report.lambda_ == lam
        assert report.cost == pytest.approx(report.distortion + lam * report.rate)
        assert report.cost == min(j for _, _, _, j in report.trials)
        assert report.rate == pytest.approx(8 * len(result.data) / len(donut_subset))
        assert report.multiplier in [m for m, _, _, _ in report.trials]


def test_a_lambda_encode_decodes_as_reconstructed(lambda_encodes):
    result, _ = lambda_encodes[0.4]
    assert Decoder().decode(result.data).equals(result.reconstruction)


def test_the_report_holds_the_kept_encode_and_the_search(lambda_run, probe):
    result, report = lambda_run[0][0.4]
    assert lambda_run[1] == [{"views": FAST_PROBE_VIEWS}] * 3
    assert "lambda 0.4" in report.summary()
    assert len(report.trials) == FAST_LAMBDA_STEPS
    assert report.distortion == pytest.approx(probe.mse(result.reconstruction))


@pytest.mark.parametrize("lam", BAD_LAMBDAS)
def test_a_bad_lambda_is_refused_naming_lambda(lam):
    for make in (Encoder, AnchorEncoder):
        with pytest.raises(InputError, match="lambda") as info:
            make(lambda_=lam)
        assert info.value.property == "lambda"


def test_lambda_excludes_quality_and_target_psnr():
    with pytest.raises(InputError, match="lambda"):
        Encoder(quality=5, lambda_=1.0)
    with pytest.raises(InputError, match="lambda"):
        Encoder(target_psnr=40.0, lambda_=1.0)
    with pytest.raises(InputError, match="lambda"):
        AnchorEncoder(quality=5, lambda_=1e-3)


def test_an_anchor_lambda_sets_the_fit_step():
    lam = 4e-4
    encoder = AnchorEncoder(lambda_=lam)
    assert step_for_lambda(lam) == pytest.approx(math.sqrt(6 * lam / math.log(2)))
    for kind in ("f", "offsets", "scaling", "semantic"):
        assert encoder.step(kind) == pytest.approx(step_for_lambda(lam))
    # lambda = 6 / (ln 2 q^2) is what a preset's base step implies: quality 5 -> f step 0.06
    assert encoder.quality == 5


def test_a_larger_anchor_lambda_gives_a_smaller_file():
    scene = small_scene()
    sizes = [len(AnchorEncoder(lambda_=lam, fit=FAST_FIT).encode(scene))
             for lam in (1e-5, 1e-4, 1e-3)]
    assert sizes[0] > sizes[1] > sizes[2]


def test_an_anchor_lambda_encode_decodes_as_reconstructed():
    result = AnchorEncoder(lambda_=2e-4, fit=FAST_FIT).encode_with_report(small_scene())
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    np.testing.assert_array_equal(decoded.features, result.reconstruction.features)
    np.testing.assert_array_equal(decoded.offsets, result.reconstruction.offsets)
    np.testing.assert_array_equal(decoded.semantic, result.reconstruction.semantic)
