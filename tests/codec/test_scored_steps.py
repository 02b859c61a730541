"""Rotation steps scored from the decoded scales and opacity (float stream scored steps,
FORMAT §12.8): the default encoder's rotation coding."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.attributes.derived_steps import (
    FOOTPRINT_MIN_GAUSSIANS,
    FOOTPRINT_WEIGHTS,
    THRESHOLDS,
    check_scored_table,
    derive_scored_classes,
    footprint_steps,
    score,
    score_features,
)
from csgs_codec.attributes.float_stream import read_float_stream
from csgs_codec.chunks.color_streams import rotation_coding_offset
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.entropy.residual import step_size
from csgs_codec.errors import FormatError, InputError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.format.primitives import ByteReader
from tests.codec.helpers import color_chunks, random_scene, rotn_channel_reader

SCENE = random_scene(6000, sh_degree=0, seed=11)
RESULT = Encoder(quality=5, hyperprior=False).encode_with_report(SCENE)


_chunks = color_chunks


def _rotn(data: bytes) -> bytes:
    return next(c.payload for c in _chunks(data) if c.type == "ROTN")


def _with_rotn(payload: bytes) -> bytes:
    return write_container([c if c.type != "ROTN" else Chunk("ROTN", c.layer, payload)
                            for c in _chunks(RESULT.data)])


def _rotn_fields(payload: bytes) -> dict[str, int]:
    """Offsets (in the ROTN payload) of the first coded channel's scored-step fields, and
    its coding ("coding_at": the coding byte's offset; "scored": whether it is set)."""
    r, coding, step_at = rotn_channel_reader(payload)
    weights_at = r.offset
    for _ in range(8):
        r.fixed("f32", "weight")
    bins_u_at = r.offset
    k_u = r.fixed("u8", "bins_u")
    thresholds_u_at = r.offset
    coding_at = rotation_coding_offset(payload)
    return {"scored": coding.scored, "coding_at": coding_at, "step_at": step_at,
            "weights_at": weights_at,
            "bins_u_at": bins_u_at, "bins_u": k_u, "thresholds_u_at": thresholds_u_at}


def _payload_offset(data: bytes) -> int:
    return read_layers(data, layers={"color"}).single_payload("ROTN")[1]


def test_the_default_encoder_writes_scored_steps_and_decodes_to_its_reconstruction():
    fields = _rotn_fields(_rotn(RESULT.data))
    assert fields["scored"] and fields["bins_u"] > 1
    assert Decoder().decode(RESULT.data).equals(RESULT.reconstruction)
    assert Decoder(threads=1).decode(RESULT.data).equals(RESULT.reconstruction)


def test_scored_steps_with_the_color_hyperprior_decode_exactly():
    from csgs_codec.decisions.color_prior_choice import PriorFitPolicy
    from csgs_codec.model.color_hyperprior import ColorFitSettings

    policy = PriorFitPolicy(ColorFitSettings(steps=60), min_gaussians=0, keep_when_larger=True)
    result = Encoder(quality=4, prior_fit=policy).encode_with_report(SCENE)
    assert "CHYP" in {c.type for c in _chunks(result.data)}
    assert _rotn_fields(_rotn(result.data))["scored"]
    for threads in (1, 2):
        assert Decoder(threads=threads).decode(result.data).equals(result.reconstruction)


def test_small_scenes_and_uniform_steps_keep_one_rotation_step():
    small = random_scene(FOOTPRINT_MIN_GAUSSIANS - 1, sh_degree=0, seed=2)
    for data in (Encoder(quality=5, hyperprior=False).encode(small),
                 Encoder(quality=5, hyperprior=False, rotation_steps="uniform").encode(SCENE)):
        r, coding, _ = rotn_channel_reader(_rotn(data))
        assert not coding.scored


def test_unknown_rotation_steps_are_refused():
    with pytest.raises(InputError, match="rotation steps"):
        Encoder(rotation_steps="sometimes")


def test_scores_follow_the_spec_order_in_binary64():
    rng = np.random.default_rng(4)
    log_scales = rng.normal(-4, 2, (300, 3)).astype(np.float32)
    opacity = rng.normal(0, 4, 300).astype(np.float32)
    weights = rng.normal(0, 3, 4).astype(np.float32)
    got = score(score_features(log_scales, opacity), weights)
    w = [float(x) for x in weights]
    for i in range(300):
        s0, s1, s2 = sorted((float(x) for x in log_scales[i]), reverse=True)
        o = min(float(opacity[i]), 0.0)
        assert got[i] == ((w[0] * s0 + w[1] * s1) + w[2] * s2) + w[3] * o  # Python floats


def test_anisotropy_weights_bin_the_spread_of_the_log_scales_exactly():
    rng = np.random.default_rng(9)
    log_scales = rng.normal(-4, 1.5, (2000, 3)).astype(np.float32)
    opacity = rng.normal(0, 3, 2000).astype(np.float32)
    thresholds = np.array(THRESHOLDS, np.float32)
    weights = np.array([(0, 0, 0, 0), (1, 0, -1, 0)], np.float32)
    cells = derive_scored_classes(log_scales, opacity, weights, np.zeros(0, np.float32),
                                  thresholds)
    s = log_scales.astype(np.float64)
    spread = s.max(axis=1) - s.min(axis=1)
    expected = [sum(float(t) <= d for t in thresholds) for d in spread]
    assert cells.tolist() == expected


def test_footprint_steps_are_finer_where_a_rotation_shows_more():
    rec = RESULT.reconstruction
    steps = footprint_steps(rec.scales, rec.opacity, 80)
    weights = np.array(FOOTPRINT_WEIGHTS, np.float32)
    features = score_features(rec.scales, rec.opacity)
    u, v = score(features, weights[0]), score(features, weights[1])
    assert np.array_equal(steps.classes, derive_scored_classes(
        rec.scales, rec.opacity, weights, steps.thresholds_u, steps.thresholds_v))
    offsets = steps.step_indices(80) - 80
    big, small = u > np.quantile(u, 0.9), u < np.quantile(u, 0.1)
    elongated, round_ = v > 1.5, v < 0.25
    assert offsets[big & elongated].mean() < offsets[small & round_].mean() - 8
    counts = np.bincount(steps.classes, minlength=steps.count)
    assert abs(np.sum(counts * steps.offsets)) / counts.sum() < 1.0  # about rate-neutral


def test_steps_of_each_cell_are_the_tables():
    rec = RESULT.reconstruction
    steps = footprint_steps(rec.scales, rec.opacity, 70)
    q = step_size(steps.step_indices(70))
    for c in range(steps.count):
        member = q[steps.classes == c]
        assert member.size == 0 or np.all(
            member == step_size(np.array([70 + steps.offsets[c]])))


@pytest.mark.parametrize("weights, tu, tv, offsets, base, message", [
    ([[np.nan, 0, 0, 0], [0, 0, 0, 0]], [], [], [0], 60, "finite"),
    ([[1, 0, 0, 0], [0, 0, 0, 0]], [0.5, 0.5], [], [0, 0, 0], 60, "strictly increasing"),
    ([[1, 0, 0, 0], [0, 0, 0, 0]], [], [np.inf], [0, 0], 60, "finite"),
    ([[1, 0, 0, 0], [0, 0, 0, 0]], [0.5], [], [0, 200], 60, "leaves"),
    ([[1, 0, 0, 0], [0, 0, 0, 0]], [0.5], [1.0], [0, 0], 60, "step offsets for 4 cells"),
    ([[1, 0, 0, 0], [0, 0, 0, 0]], list(range(8)), [], [0] * 9, 60, "at most 8"),
])
def test_bad_scored_tables_are_named(weights, tu, tv, offsets, base, message):
    why = check_scored_table(np.array(weights, np.float32), np.array(tu, np.float32),
                             np.array(tv, np.float32), np.array(offsets), base)
    assert message in why


def test_a_nan_weight_is_rejected_at_the_first_weight():
    payload = bytearray(_rotn(RESULT.data))
    at = _rotn_fields(bytes(payload))["weights_at"]
    payload[at + 8:at + 12] = bytes([0, 0, 0xC0, 0x7F])  # the third weight of u: NaN
    data = _with_rotn(bytes(payload))
    with pytest.raises(FormatError, match="weights must be finite") as info:
        Decoder().decode(data)
    assert (info.value.chunk, info.value.offset) == ("ROTN", _payload_offset(data) + at)


def test_unsorted_thresholds_and_bad_bin_counts_are_rejected():
    payload = _rotn(RESULT.data)
    fields = _rotn_fields(payload)
    swapped = bytearray(payload)
    at = fields["thresholds_u_at"]
    swapped[at:at + 8] = payload[at + 4:at + 8] + payload[at:at + 4]
    with pytest.raises(FormatError, match="strictly increasing") as info:
        Decoder().decode(_with_rotn(bytes(swapped)))
    assert info.value.offset == _payload_offset(RESULT.data) + fields["weights_at"]
    for count in (0, 9):
        bad = bytearray(payload)
        bad[fields["bins_u_at"]] = count
        with pytest.raises(FormatError, match="bins of score u") as info:
            Decoder().decode(_with_rotn(bytes(bad)))
        assert info.value.offset == _payload_offset(RESULT.data) + fields["bins_u_at"] + 1


def test_scored_steps_outside_rotations_are_rejected():
    payload = _rotn(RESULT.data)
    r = ByteReader(payload)
    r.byte_string("axis_stream")
    with pytest.raises(FormatError, match="only allowed in ROTN") as info:
        read_float_stream(ByteReader(payload[r.offset:], chunk="SCAL"), len(SCENE), 3)
    assert info.value.chunk == "SCAL"


def test_damaged_scored_step_payloads_only_raise_format_error():
    payload = _rotn(RESULT.data)
    fields = _rotn_fields(payload)
    rng = np.random.default_rng(17)
    decoded = 0
    for trial in range(150):
        damaged = bytearray(payload)
        at = (int(rng.integers(fields["step_at"], fields["thresholds_u_at"] + 200))
              if trial % 3 else int(rng.integers(0, len(payload))))
        damaged[at] = int(rng.integers(0, 256))
        try:
            Decoder(threads=1).decode(_with_rotn(bytes(damaged)))
            decoded += 1
        except FormatError as err:
            assert err.chunk == "ROTN"
    assert decoded < 150


def test_the_encoding_is_deterministic():
    assert Encoder(quality=5, hyperprior=False).encode(SCENE) == RESULT.data


def test_the_cli_writes_footprint_steps_by_default_and_uniform_on_request(tmp_path):
    from csgs_cli.main import main
    from tests.conftest import SAMPLE

    paths = {}
    for name, extra in (("default", []), ("uniform", ["--rotation-steps", "uniform"])):
        paths[name] = tmp_path / f"{name}.csgs"
        assert main(["-q", "encode", str(SAMPLE), "-o", str(paths[name]), "--quality", "3",
                     "--no-hyperprior", *extra]) == 0
    scored = {name: rotn_channel_reader(_rotn(p.read_bytes()))[1].scored
              for name, p in paths.items()}
    assert scored == {"default": True, "uniform": False}
    out = tmp_path / "gone.csgs"
    for retired in (["--uniform-steps"], ["--rotation-steps", "anisotropy"]):
        with pytest.raises(SystemExit) as info:
            main(["-q", "encode", str(SAMPLE), "-o", str(out), *retired])
        assert info.value.code == 2 and not out.exists()


def test_info_reports_the_rotation_steps(tmp_path):
    from csgs_codec.codec.describe import describe_bitstream

    path = tmp_path / "s.csgs"
    path.write_bytes(RESULT.data)
    steps = describe_bitstream(str(path))["rotation_steps"]
    assert (steps["name"], steps["classes"]) == ("footprint", 64)
    assert steps["coding"] in ("frozen+scored", "frozen+predicted+scored")
    uniform = Encoder(quality=5, hyperprior=False, rotation_steps="uniform").encode(SCENE)
    assert describe_bitstream(uniform)["rotation_steps"]["name"] == "uniform"
    cut = RESULT.data[:len(RESULT.data) - 1000]  # the ROTN chunk is cut off
    assert "rotation_steps" not in describe_bitstream(cut, verify=False)
