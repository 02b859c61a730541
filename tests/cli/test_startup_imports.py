"""Every ``csgs`` command builds the whole parser, so building it must not import torch:
that alone takes seconds and would make ``csgs info`` and ``csgs decode`` slow to start."""

from __future__ import annotations

import subprocess
import sys


def test_building_the_cli_parser_loads_no_torch():
    code = ("import sys; from csgs_cli.main import build_parser; build_parser(); "
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_train_option_defaults_match_the_settings_classes():
    from csgs_cli.main import build_parser
    from csgs_codec.train.color_stage import ColorStageSettings
    from csgs_codec.train.pipeline import TrainSettings

    args = build_parser().parse_args(["train", "data", "-o", "x.csgs"])
    color, train = ColorStageSettings(), TrainSettings()
    assert (args.iterations, args.quality, args.anchors, args.max_anchors, args.features,
            args.offsets, args.threads, args.rate_weight) == (
        color.iterations, color.quality, color.initial_anchors, color.max_anchors,
        color.feat_dim, color.n_offsets, color.threads, color.rate_weight)
    assert (args.semantic_iterations, args.semantic_rate, args.semantic_margin) == (
        train.semantic_iterations, train.feature_rate_weight, train.contrastive_margin)
