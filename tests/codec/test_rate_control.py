"""--target-psnr: the smallest encode whose probe renders reach a foreground PSNR."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions.presets import PRESETS, scaled_preset
from csgs_codec.decisions.rate_control import LOG2_LO, RenderProbe
from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.interchange.ply_io import read_ply
from tests.codec.helpers import steps_of
from tests.conftest import SAMPLE


@pytest.fixture(scope="module")
def small_scene():
    scene = read_ply(SAMPLE)
    return scene.subset(np.random.default_rng(0).permutation(len(scene))[:4000])


@pytest.fixture(scope="module")
def probe(small_scene):
    return RenderProbe(small_scene, views=2, size=(96, 72))


def test_scaled_presets_reproduce_the_preset_ladder():
    for quality, p in PRESETS.items():
        scaled = scaled_preset(p.dc_step / PRESETS[8].dc_step)
        assert scaled.position_bits == p.position_bits
        assert scaled.quality == quality
        assert scaled.opacity_step == pytest.approx(p.opacity_step)


@pytest.mark.parametrize("target", [30.0, 42.0])
def test_the_target_is_met_and_decodes_as_reconstructed(small_scene, probe, target,
                                                         monkeypatch):
    monkeypatch.setattr("csgs_codec.decisions.rate_control.RenderProbe", lambda scene: probe)
    result = Encoder(target_psnr=target).encode_with_report(small_scene)
    report = result.rate_control
    assert report.psnr >= target
    assert probe.psnr(result.reconstruction) == pytest.approx(report.psnr)
    assert Decoder().decode(result.data).equals(result.reconstruction)
    # the kept encode is the coarsest trial that met the target
    met = [m for m, _, psnr in report.trials if psnr >= target]
    assert report.multiplier == pytest.approx(max(met))


def test_a_higher_target_gives_a_larger_file(small_scene, probe, monkeypatch):
    monkeypatch.setattr("csgs_codec.decisions.rate_control.RenderProbe", lambda scene: probe)
    low = Encoder(target_psnr=28.0).encode(small_scene)
    high = Encoder(target_psnr=45.0).encode(small_scene)
    assert len(high) > len(low)


def test_an_unreachable_target_warns_and_keeps_the_finest_encode(small_scene, probe,
                                                                 monkeypatch):
    monkeypatch.setattr("csgs_codec.decisions.rate_control.RenderProbe", lambda scene: probe)
    with pytest.warns(CsgsWarning, match="not reached"):
        result = Encoder(target_psnr=89.0).encode_with_report(small_scene)
    assert result.rate_control.multiplier == pytest.approx(2.0 ** LOG2_LO)


@pytest.mark.parametrize("target", [float("nan"), 3.0, 200.0])
def test_a_target_outside_the_range_is_refused(small_scene, target):
    with pytest.raises(InputError, match="target PSNR"):
        Encoder(target_psnr=target).encode(small_scene)


def test_a_refined_final_encode_still_meets_the_target(small_scene, probe, monkeypatch):
    """The search runs without refinement; its settings are encoded once more refined, and
    that file is kept only where it still reaches the target on the probe views."""
    monkeypatch.setattr("csgs_codec.decisions.rate_control.RenderProbe", lambda scene: probe)
    steps = []
    result = Encoder(target_psnr=34.0, refine=3, hyperprior=False,
                     progress=steps_of("refinement", steps, lambda done, total: done)
                     ).encode_with_report(small_scene)
    assert steps == [1, 2, 3]  # the trials were not refined, the final encode was
    assert result.rate_control.psnr >= 34.0
    assert probe.psnr(result.reconstruction) == pytest.approx(result.rate_control.psnr)
    assert Decoder().decode(result.data).equals(result.reconstruction)


def test_a_refined_encode_that_misses_the_target_falls_back_to_the_hyperprior_encode(
        small_scene, probe, monkeypatch):
    """When the refined final encode renders below the target, the searched settings are
    coded once more without refinement, with the color hyperprior."""
    from csgs_codec.decisions.color_prior_choice import PriorFitPolicy
    from csgs_codec.model.color_hyperprior import ColorFitSettings

    refined = []

    class PessimisticAboutRefinement:
        """The real probe, except that the first score after refinement ran is 0 dB."""

        def psnr(self, candidate):
            if refined and refined[-1] == "unscored":
                refined[-1] = "scored"
                return 0.0
            return probe.psnr(candidate)

    monkeypatch.setattr("csgs_codec.decisions.rate_control.RenderProbe",
                        lambda scene: PessimisticAboutRefinement())
    policy = PriorFitPolicy(ColorFitSettings(steps=60, batch=256), min_gaussians=0,
                            keep_when_larger=True)
    fits = []

    def progress(stage: str, done: int, total: int) -> None:
        if stage == "refinement" and total and done == total:
            refined.append("unscored")
        elif stage == "color hyperprior" and total:
            fits.append(list(refined))

    result = Encoder(target_psnr=34.0, refine=2, prior_fit=policy,
                     progress=progress).encode_with_report(small_scene)
    assert refined == ["scored"]
    # the fit ran once, after the refined encode was scored and refused (the search's
    # trials run without the hyperprior, the refined final encode with it)
    assert [f for f in fits if f == ["scored"]] and not [f for f in fits if f == []]
    assert result.rate_control.psnr >= 34.0
    assert probe.psnr(result.reconstruction) == pytest.approx(result.rate_control.psnr)
    assert Decoder().decode(result.data).equals(result.reconstruction)
