"""EncoderConfig: one frozen value decides what an Encoder writes; Encoder takes it or its
fields as keywords, and one ``progress(stage, done, total)`` callback (issue #33)."""

from __future__ import annotations

import dataclasses

import pytest

from csgs_codec import Encoder, EncoderConfig
from csgs_codec.attributes.position_grid import PositionGrid
from csgs_codec.codec.encoder import COUNTED_STAGES
from csgs_codec.codec.tile_encoder import plan_jobs
from csgs_codec.decisions.color_prior_choice import PriorFitPolicy
from csgs_codec.errors import InputError
from csgs_codec.model.color_hyperprior import ColorFitSettings
from tests.codec.helpers import random_scene


def test_a_config_and_its_fields_as_keywords_make_the_same_encoder():
    config = EncoderConfig(quality=7, rotation_steps="uniform", semantic="none")
    assert Encoder(config).config == config
    assert Encoder(quality=7, rotation_steps="uniform", semantic="none").config == config
    assert Encoder(7).config.quality == 7 and Encoder().config == EncoderConfig()
    # Keywords override the config's fields.
    assert Encoder(config, quality=3).config == dataclasses.replace(config, quality=3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.quality = 2


def test_the_same_config_writes_the_same_bytes():
    scene = random_scene(300, sh_degree=1, seed=3)
    config = EncoderConfig(quality=4, hyperprior=False, rotation_steps="uniform")
    fields = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    assert Encoder(config).encode(scene) == Encoder(**fields).encode(scene)


@pytest.mark.parametrize("fields, name", [
    ({"quality": 0}, "quality"), ({"quality": 3, "lambda_": 0.1}, "lambda"),
    ({"semantic": "all"}, "semantic"), ({"prune_opacity": 1.5}, "prune_opacity"),
    ({"rotation_steps": "random"}, "rotation_steps"), ({"refine": True}, "refine"),
    ({"workers": 0}, "workers"), ({"ray": " "}, "ray"), ({"view_budget": 11}, "view_budget"),
    ({"step_allocation": "yes"}, "step_allocation"), ({"prior_fit": 3}, "prior_fit")])
def test_bad_values_are_refused_naming_the_field(fields, name):
    with pytest.raises(InputError) as err:
        EncoderConfig(**fields)
    assert name in str(err.value) or err.value.property == name


def test_an_unknown_setting_is_refused_by_name():
    with pytest.raises(InputError, match="tile_progress"):
        Encoder(tile_progress=print)


def test_tiles_are_coded_with_the_encoders_config():
    scene = random_scene(1200, seed=2)
    policy = PriorFitPolicy(ColorFitSettings(steps=40), min_gaussians=0)
    encoder = Encoder(quality=6, rotation_steps="uniform", prior_fit=policy, tile_size=400,
                      workers=2)
    grid = PositionGrid.fit(scene.positions, encoder.preset.position_bits)
    jobs = plan_jobs(encoder, scene.positions, grid, encoder.preset, 400, hyperprior=False,
                     scene=scene)
    assert len(jobs) == 4  # k-d cells of at most 400
    for job in jobs:
        assert job.encoder_class is Encoder
        # One tile, one worker; any view pruning ran on the whole scene before tiling.
        assert job.config == dataclasses.replace(encoder.config, hyperprior=False,
                                                 tile_size=None, workers=1,
                                                 view_pruning=False)


def test_progress_reports_stages_and_the_steps_of_the_counted_ones():
    calls = []
    policy = PriorFitPolicy(ColorFitSettings(steps=60, batch=256), min_gaussians=0)
    Encoder(quality=5, prior_fit=policy, step_allocation=True,
            progress=lambda stage, done, total: calls.append((stage, done, total))
            ).encode(random_scene(1500, sh_degree=1, seed=4))
    started = [stage for stage, done, total in calls if not total]
    counted = {stage for stage, done, total in calls if total}
    assert started[:2] == ["step allocation", "geometry"] and "color hyperprior" in started
    assert counted == {"step allocation", "color hyperprior"} <= set(COUNTED_STAGES)
    fit = [(done, total) for stage, done, total in calls if stage == "color hyperprior" and total]
    assert fit[-1] == (60, 60)


def test_views_are_pruned_by_default_exactly_when_cameras_are_given():
    """The API's default agrees with `csgs encode`: cameras known, pruning on."""
    from csgs_codec.render.view_distribution import default_distribution

    cameras = default_distribution(random_scene(50, seed=1), directions=2).cameras
    assert not Encoder().config.prunes_views and Encoder(view_pruning=True).config.prunes_views
    assert Encoder(cameras=cameras).config.prunes_views
    assert not Encoder(cameras=cameras, view_pruning=False).config.prunes_views
    with pytest.raises(InputError, match="view_pruning"):
        EncoderConfig(view_pruning="yes")


def test_the_config_is_the_one_place_an_encoders_settings_live():
    """No field is copied onto the Encoder, where a later change to one would not reach
    the other: settings are read from ``encoder.config`` only."""
    encoder = Encoder(quality=3, fast=True)
    for name in EncoderConfig.field_names():
        assert name not in vars(encoder), name
    assert not encoder.config.fits_hyperprior and Encoder().config.fits_hyperprior
