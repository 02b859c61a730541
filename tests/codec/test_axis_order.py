"""The encoder sorts each Gaussian's axes by scale where that codes smaller (axis_order)."""

from __future__ import annotations

import numpy as np

import csgs_codec.codec.encoder as encoder_module
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions.axis_order import sorted_axes_pay
from csgs_codec.decisions.presets import preset
from tests.codec.helpers import random_scene


def _with_rotations(near_identity: bool, n: int = 6000):
    scene = random_scene(n, sh_degree=0, seed=3)
    rng = np.random.default_rng(4)
    q = rng.normal(size=(n, 4))
    if near_identity:
        q = np.concatenate([np.ones((n, 1)), 0.05 * rng.normal(size=(n, 3))], axis=1)
    scene.rotations = (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)
    scene.scales = rng.normal(-4.0, 1.0, size=(n, 3)).astype(np.float32)
    return scene


def test_spread_rotations_sort_and_rotations_near_the_identity_do_not():
    assert sorted_axes_pay(_with_rotations(near_identity=False), preset(5))
    assert not sorted_axes_pay(_with_rotations(near_identity=True), preset(5))


def test_a_sorted_encode_decodes_to_its_reconstruction_and_codes_smaller(monkeypatch):
    scene = _with_rotations(near_identity=False)
    result = Encoder(quality=5, hyperprior=False).encode_with_report(scene)
    assert result.sorted_axes is True
    decoded = Decoder().decode(result.data)
    assert decoded.equals(result.reconstruction)
    # Sorted before quantization (all but the Gaussians the guard of
    # canonical_orientations keeps); channels quantize around their own means, so a near tie
    # may come back out of order by up to a step.
    ordered = np.all(np.diff(decoded.scales, axis=1) <= preset(5).scale_step, axis=1)
    assert ordered.mean() > 0.9
    # The same encoder with the decision turned the other way.
    monkeypatch.setattr(encoder_module, "sorted_axes_pay", lambda scene, p: False)
    kept = Encoder(quality=5, hyperprior=False).encode_with_report(scene)
    assert kept.sorted_axes is False
    assert result.stream_bytes["SCAL"] < 0.95 * kept.stream_bytes["SCAL"]
