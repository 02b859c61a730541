"""The AMLP payload: version 2 (float streams) written, version 1 (float16) still read, and a
decoder's allocation bounded by the bytes it was given."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.chunks import anchor_payloads as ap
from csgs_codec.entropy.residual import CODED_VALUE_SLACK
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteWriter
from csgs_codec.scene.anchor_scene import MLPWeights, ScaffoldMLPWeights

F, K = 8, 3


def _mlps(seed: int = 0, appearance: np.ndarray | None = None) -> ScaffoldMLPWeights:
    rng = np.random.default_rng(seed)
    extra = 0 if appearance is None else appearance.shape[1]

    def head(inputs: int, outputs: int) -> MLPWeights:
        return MLPWeights(rng.normal(0, 0.2, (F, inputs)).astype(np.float32),
                          rng.normal(0, 0.05, F).astype(np.float32),
                          rng.normal(0, 0.2, (outputs, F)).astype(np.float32),
                          np.zeros(outputs, np.float32))

    return ScaffoldMLPWeights(opacity=head(F + 3, K), cov=head(F + 3, 7 * K),
                              color=head(F + 3 + extra, 3 * K), appearance=appearance)


def _same(a: ScaffoldMLPWeights, b: ScaffoldMLPWeights) -> bool:
    return all(np.array_equal(x, y) for name in a.heads()
               for x, y in zip(a.heads()[name].arrays().values(),
                               b.heads()[name].arrays().values()))


@pytest.mark.parametrize("multiplier", [0.4, 3.0, 12.0])
def test_version_2_decodes_to_the_encoders_reconstruction(multiplier):
    original = _mlps()
    payload, recon = ap.mlps_to_bytes(original, multiplier)
    assert payload[0] == ap.MLP_VERSION == 2
    decoded = ap.mlps_from_bytes(payload, F, K)
    assert _same(decoded, recon)
    w = original.cov.w1
    step = float(np.std(w)) * ap.MLP_RELATIVE_STEP * multiplier
    assert np.abs(decoded.cov.w1 - w).max() <= step * 0.53  # steps sit on a 1/8-octave grid
    assert np.array_equal(decoded.opacity.b2, original.opacity.b2)  # zeros: a constant


def test_version_2_is_smaller_than_float16_at_the_default_quality():
    original = _mlps()
    v2, _ = ap.mlps_to_bytes(original, 3.0)
    v1, _ = ap.mlps_to_bytes(original, 3.0, version=ap.MLP_VERSION_F16)
    assert len(v2) < 0.6 * len(v1)


def test_version_1_files_still_decode_as_float16():
    original = _mlps()
    payload, recon = ap.mlps_to_bytes(original, version=ap.MLP_VERSION_F16)
    assert payload[0] == 1
    decoded = ap.mlps_from_bytes(payload, F, K)
    assert _same(decoded, recon)
    assert np.array_equal(decoded.color.w1,
                          original.color.w1.astype(np.float16).astype(np.float32))


def test_huge_near_constant_arrays_fall_back_to_float16():
    appearance = np.zeros((CODED_VALUE_SLACK // 4 + 1, 8), np.float32)  # > the slack
    payload, recon = ap.mlps_to_bytes(_mlps(appearance=appearance), 3.0)
    assert payload[0] == ap.MLP_VERSION_F16
    assert np.array_equal(recon.appearance, appearance)


def test_a_decoder_refuses_an_array_too_large_for_the_bytes_left():
    out = ByteWriter()
    out.fixed("u8", ap.MLP_VERSION)
    out.fixed("u8", 0)
    for width in (4096, 4096, 4096):  # H, D, O at their limit: 16.7M weights in w1
        out.varint(width)
    with pytest.raises(FormatError, match="opacity.w1.*exceed"):
        ap.mlps_from_bytes(out.getvalue(), F, K)


def test_unknown_versions_are_refused_on_both_sides():
    payload, _ = ap.mlps_to_bytes(_mlps(), 3.0)
    with pytest.raises(FormatError, match="version 3"):
        ap.mlps_from_bytes(bytes([3]) + payload[1:], F, K)
    with pytest.raises(Exception, match="version"):
        ap.mlps_to_bytes(_mlps(), version=3)
