"""The hyperprior fit never leaves NaN or Inf behind: extreme anchor scenes encode exactly or
are refused, and a fit that diverges restarts or falls back and says so."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.codec.anchor_encoder import AnchorEncoder
from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.model import anchor_hyperprior, fit_tools
from csgs_codec.model.anchor_hyperprior import GRAD_CLIP_NORM, FitSettings
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene

SHORT_FIT = FitSettings(steps=30, batch=256)
FIELDS = ("positions", "features", "offsets", "scaling", "offset_mask", "semantic", "labels")


def base_scene():
    return synthetic_anchor_scene(2, 40, seed=5)


def _features_1e6(s):
    s.features[:] = 1e6 * np.sign(s.features)


def _features_times_1e6(s):
    s.features *= np.float32(1e6)


def _offsets_1e_30(s):
    s.offsets[:] = np.float32(1e-30)


def _offsets_1e4(s):
    s.offsets[:] = np.float32(1e4) * np.sign(s.offsets)


def _scaling_minus_30_to_10(s):
    s.scaling[:] = np.random.default_rng(0).uniform(-30, 10, s.scaling.shape)


def _identical_anchors(s):
    for name in ("features", "offsets", "scaling", "semantic"):
        getattr(s, name)[:] = getattr(s, name)[0]
    s.offset_mask[:] = s.offset_mask[0]


def _one_anchor(s):
    return s.subset(np.arange(1))


def _two_anchors(s):
    return s.subset(np.arange(2))


def _all_offsets_masked(s):
    s.offset_mask[:] = False


def _denormal_features(s):
    s.features[:] = np.float32(1e-40)


EXTREMES = [_features_1e6, _features_times_1e6, _offsets_1e_30, _offsets_1e4,
            _scaling_minus_30_to_10, _identical_anchors, _one_anchor, _two_anchors,
            _all_offsets_masked, _denormal_features]


def encode_quietly(scene, **kwargs):
    """Encode with the short fit; (result, CsgsWarning messages)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = AnchorEncoder(fit=kwargs.pop("fit", SHORT_FIT), **kwargs).encode_with_report(
            scene)
    return result, [str(w.message) for w in caught if issubclass(w.category, CsgsWarning)]


def assert_decodes_as_reconstructed(result):
    decoded = AnchorDecoder().decode(result.data, layers="color,semantic")
    for name in FIELDS:
        expected = getattr(result.reconstruction, name)
        if expected is None:
            assert getattr(decoded, name) is None
        else:
            np.testing.assert_array_equal(getattr(decoded, name), expected)
    for name in ("features", "offsets", "scaling", "semantic"):
        values = getattr(decoded, name)
        assert values is None or np.all(np.isfinite(values))


@pytest.mark.parametrize("edit", EXTREMES, ids=lambda f: f.__name__.lstrip("_"))
def test_an_extreme_anchor_scene_encodes_and_decodes_exactly(edit):
    scene = base_scene()
    scene = edit(scene) or scene
    result, _ = encode_quietly(scene)
    assert_decodes_as_reconstructed(result)
    kept = scene.subset(result.order)
    bound = result.steps["f"][:, None] / 2 + 2.0**-13
    error = np.abs(result.reconstruction.features.astype(np.float64) - kept.features)
    assert np.all(error <= bound * (1 + 1e-6) + np.abs(kept.features) * 2.0**-23)


@pytest.mark.parametrize("name,value", [("features", 1e8), ("features", 3e38),
                                        ("offsets", -1e12), ("scaling", 2.0**25),
                                        ("semantic", 1e9)])
def test_a_value_beyond_2_to_the_24_is_refused_naming_the_attribute(name, value):
    scene = base_scene()
    getattr(scene, name).reshape(len(scene), -1)[3, 0] = value
    scene.offset_mask[3, 0] = True
    with pytest.raises(InputError, match="2\\^24") as info:
        AnchorEncoder(fit=SHORT_FIT).encode(scene)
    assert info.value.property == name


def test_a_huge_masked_offset_is_not_coded_and_not_refused():
    scene = base_scene()
    scene.offset_mask[3, 0] = False
    scene.offsets[3, 0] = 1e30
    result, messages = encode_quietly(scene)
    assert messages == []
    assert_decodes_as_reconstructed(result)


def _nan_loss_for(attempts: int):
    """A replacement for _Prior.loss that returns NaN during the first ``attempts`` fits."""
    original = anchor_hyperprior._Prior.loss
    seen = []  # the priors themselves, kept alive so no two share an identity

    def loss(self, *args):
        if not any(prior is self for prior in seen):
            seen.append(self)
        value = original(self, *args)
        return value * float("nan") if len(seen) <= attempts else value

    return loss


def test_a_diverging_fit_restarts_once_and_says_so(monkeypatch):
    monkeypatch.setattr(anchor_hyperprior._Prior, "loss", _nan_loss_for(1))
    result, messages = encode_quietly(base_scene(), semantic="none")
    assert len(messages) == 1
    assert "non-finite loss at step 0" in messages[0] and "restarting" in messages[0]
    assert_decodes_as_reconstructed(result)


def test_a_fit_that_diverges_twice_falls_back_to_the_factorized_prior(monkeypatch):
    monkeypatch.setattr(anchor_hyperprior._Prior, "loss", _nan_loss_for(2))
    result, messages = encode_quietly(base_scene(), semantic="none")
    assert len(messages) == 2
    assert "restarting" in messages[0] and "factorized prior" in messages[1]
    assert_decodes_as_reconstructed(result)


def test_the_fallback_prior_predicts_the_same_parameters_everywhere(monkeypatch):
    monkeypatch.setattr(anchor_hyperprior._Prior, "loss", _nan_loss_for(2))
    scene = base_scene()
    cells = np.random.default_rng(0).integers(0, 64, size=(50, 3))
    target = anchor_hyperprior.AttributeTarget(scene.scaling[:1].repeat(50, 0).astype(float),
                                               np.ones((50, 6)), 0.01)
    with pytest.warns(CsgsWarning):
        hyper, carm = anchor_hyperprior.fit_prior(cells, 6, [target], settings=SHORT_FIT)
    outputs = hyper.forward(cells)
    assert np.all(outputs == outputs[0])


def test_a_huge_learning_rate_ends_in_the_fallback_and_decodes_exactly():
    result, messages = encode_quietly(base_scene(), fit=FitSettings(steps=30, batch=256,
                                                                      learning_rate=1e6))
    assert any("restarting" in m for m in messages)
    assert any("factorized prior" in m for m in messages)
    assert_decodes_as_reconstructed(result)


def test_an_ordinary_fit_neither_restarts_nor_falls_back():
    _, messages = encode_quietly(base_scene())
    assert messages == []


def test_gradients_above_the_clip_norm_are_scaled_to_it():
    params = [torch.zeros(3, requires_grad=True), torch.zeros(2, requires_grad=True)]
    params[0].grad = torch.full((3,), 4000.0)
    params[1].grad = torch.full((2,), -3000.0)
    norm = fit_tools.clip_gradients(params, GRAD_CLIP_NORM)
    assert norm == pytest.approx(np.sqrt(3 * 4000.0**2 + 2 * 3000.0**2))
    total = torch.sqrt(sum((p.grad.double() ** 2).sum() for p in params))
    assert float(total) == pytest.approx(GRAD_CLIP_NORM)


def test_gradients_below_the_clip_norm_are_untouched():
    param = torch.zeros(2, requires_grad=True)
    param.grad = torch.tensor([3.0, 4.0])
    assert fit_tools.clip_gradients([param], GRAD_CLIP_NORM) == pytest.approx(5.0)
    assert param.grad.tolist() == [3.0, 4.0]


def test_a_non_finite_gradient_is_reported_as_such():
    param = torch.zeros(2, requires_grad=True)
    param.grad = torch.tensor([float("inf"), 1.0])
    assert not np.isfinite(fit_tools.clip_gradients([param], GRAD_CLIP_NORM))
