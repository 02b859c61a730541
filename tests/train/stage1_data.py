"""Small shared inputs for the stage-1 and pipeline tests (cached per process)."""

from __future__ import annotations

import functools

from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.train.color_stage import ColorStageSettings
from csgs_codec.train.pipeline import TrainSettings
from csgs_codec.train.synthetic import SyntheticDataset, make_synthetic_dataset


@functools.cache
def tiny_dataset(seed: int = 0) -> SyntheticDataset:
    """3 objects x 120 Gaussians, 6 views of 48x36 pixels."""
    return make_synthetic_dataset(seed, objects=3, gaussians_per_object=120, views=6,
                                  width=48, height=36)


def tiny_color_settings(**overrides) -> ColorStageSettings:
    """Stage-1 settings that train the tiny dataset in a few seconds (to about 30 dB)."""
    values = dict(iterations=150, initial_anchors=60, feat_dim=8, n_offsets=4,
                  max_anchors=200, growth_every=30, rate_weight=0.01,
                  learning_rates={"features": 0.02, "offsets": 0.02, "scaling": 0.01,
                                  "mask_logits": 0.01, "mlps": 0.01, "rate": 0.005})
    values.update(overrides)
    return ColorStageSettings(**values)


def tiny_train_settings(**overrides) -> TrainSettings:
    """Whole-run settings for the tiny dataset (short semantic stages, quick encoder fit)."""
    color = tiny_color_settings(**overrides.pop("color", {}))
    values = dict(semantic_iterations=30, stage3_iterations=20, checkpoint_every=70,
                  encoder_fit=FitSettings(steps=40, batch=256))
    values.update(overrides)
    return TrainSettings(color, **values)
