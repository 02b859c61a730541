"""Rotation steps derived from the decoded scales (float stream mode 6, FORMAT §12.8)."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.derived_steps import (
    THRESHOLDS,
    check_table,
    derive_classes,
    rotation_steps,
)
from csgs_codec.codec.encoder import Encoder
from csgs_codec.codec.float_stream import MODE_DERIVED, read_float_stream
from csgs_codec.entropy.residual import step_size
from csgs_codec.errors import FormatError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.format.primitives import ByteReader
from tests.codec.helpers import color_chunks, random_scene, rotn_channel_reader

SCENE = random_scene(3000, sh_degree=0, seed=3)
RESULT = Encoder(quality=5, rotation_steps="anisotropy").encode_with_report(SCENE)


_chunks = color_chunks


def _rotn_fields(payload: bytes) -> dict[str, int]:
    """Offsets (in the ROTN payload) of channel 0's fields, and its mode and class count."""
    r, mode, step_at = rotn_channel_reader(payload)
    k = r.fixed("u8", "class_count")
    return {"mode": mode, "step_at": step_at, "thresholds_at": r.offset, "classes": k}


def test_derived_steps_decode_to_the_encoders_reconstruction():
    fields = _rotn_fields(_chunks(RESULT.data)[-1].payload)
    assert fields["mode"] == MODE_DERIVED and fields["classes"] == len(THRESHOLDS) + 1
    assert Decoder().decode(RESULT.data).equals(RESULT.reconstruction)
    assert Decoder(threads=1).decode(RESULT.data).equals(RESULT.reconstruction)


def _angle_error(result) -> np.ndarray:
    """(N,) rotation error (radians) of each decoded Gaussian of ``result``."""
    a = SCENE.subset(result.order).rotations.astype(np.float64)
    b = result.reconstruction.rotations.astype(np.float64)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    return 2 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0, 1))


def test_rotation_error_follows_the_derived_step():
    """Near-isotropic Gaussians get coarser rotation steps than elongated ones, and the
    most elongated finer ones than the plain encode's."""
    error = _angle_error(RESULT)
    classes = derive_classes(RESULT.reconstruction.scales, np.array(THRESHOLDS, np.float32))
    top = classes.max()
    assert error[classes == 0].mean() > 2 * error[classes == top].mean()
    plain = Encoder(quality=5).encode_with_report(SCENE)
    plain_classes = derive_classes(plain.reconstruction.scales,
                                   np.array(THRESHOLDS, np.float32))
    assert error[classes == top].mean() < _angle_error(plain)[plain_classes == top].mean()


def test_derived_steps_are_deterministic():
    again = Encoder(quality=5, rotation_steps="anisotropy").encode(SCENE)
    assert again == RESULT.data
    assert Encoder(quality=5).encode(SCENE) != RESULT.data


def test_classes_count_thresholds_at_or_below_the_anisotropy():
    scales = np.array([[0, 0, 0], [0, 0.25, 0], [-1, 0, 1], [0, 0, 3.0], [-5, 5, 0]],
                      np.float32)
    classes = derive_classes(scales, np.array(THRESHOLDS, np.float32))
    assert classes.tolist() == [0, 1, 6, 7, 7]


def test_encoder_table_is_coarser_for_isotropic_classes():
    scales = np.random.default_rng(0).normal(-4, 0.7, (5000, 3)).astype(np.float32)
    derived = rotation_steps(scales, 60)
    assert derived.offsets[0] > 0 > derived.offsets[-1]
    assert np.all(np.diff(derived.offsets) <= 0)
    assert check_table(derived.thresholds, derived.offsets, 60) is None


@pytest.mark.parametrize("thresholds, offsets, base, message", [
    ([0.5, 0.25], [0, 0, 0], 60, "strictly increasing"),
    ([-0.1], [0, 0], 60, ">= 0"),
    ([float("nan")], [0, 0], 60, "finite"),
    ([0.5], [0, 200], 60, "leaves"),
    ([0.5], [-61, 0], 60, "leaves"),
    ([], [], 60, "class count"),
])
def test_bad_tables_are_named(thresholds, offsets, base, message):
    assert message in check_table(np.array(thresholds, np.float32), np.array(offsets), base)


def _with_rotn(payload: bytes) -> bytes:
    chunks = _chunks(RESULT.data)
    return write_container([c if c.type != "ROTN" else Chunk("ROTN", c.layer, payload)
                            for c in chunks])


def _payload_offset(data: bytes) -> int:
    """Absolute offset of the ROTN payload's first byte in ``data``."""
    return read_layers(data, layers={"color"}).single_payload("ROTN")[1]


def test_decreasing_thresholds_are_rejected_at_their_offset():
    payload = bytearray(_chunks(RESULT.data)[-1].payload)
    at = _rotn_fields(bytes(payload))["thresholds_at"]
    payload[at:at + 4] = np.float32(9.0).tobytes()  # first threshold above the second
    data = _with_rotn(bytes(payload))
    with pytest.raises(FormatError, match="strictly increasing") as info:
        Decoder().decode(data)
    assert info.value.chunk == "ROTN"
    assert info.value.offset == _payload_offset(data) + at


def test_a_step_index_the_offsets_push_off_the_table_is_rejected():
    payload = bytearray(_chunks(RESULT.data)[-1].payload)
    fields = _rotn_fields(bytes(payload))
    payload[fields["step_at"]] = 175  # the finest class's offset is negative: ok; coarse: off
    data = _with_rotn(bytes(payload))
    with pytest.raises(FormatError, match="leaves") as info:
        Decoder().decode(data)
    assert info.value.chunk == "ROTN"
    assert info.value.offset == _payload_offset(data) + fields["thresholds_at"]


def test_mode_6_outside_rotations_is_rejected():
    payload = _chunks(RESULT.data)[-1].payload
    r = ByteReader(payload, chunk="SCAL")
    r.byte_string("axis_stream")
    body = payload[r.offset:]
    with pytest.raises(FormatError, match="only allowed in ROTN") as info:
        read_float_stream(ByteReader(body, chunk="SCAL"), len(SCENE), 3)
    assert info.value.chunk == "SCAL"


def test_steps_of_each_class_are_the_tables():
    derived = rotation_steps(RESULT.reconstruction.scales, 70)
    steps = step_size(derived.step_indices(70))
    for c in range(derived.count):
        member = steps[derived.classes == c]
        assert member.size == 0 or np.all(member == step_size(np.array([70 + derived.offsets[c]])))


def test_damaged_derived_step_payloads_only_raise_format_error():
    payload = _chunks(RESULT.data)[-1].payload
    fields = _rotn_fields(payload)
    rng = np.random.default_rng(7)
    # Mostly the mode-6 record's header (table, offsets, scale indices), some anywhere.
    for trial in range(150):
        damaged = bytearray(payload)
        at = (int(rng.integers(fields["step_at"], fields["thresholds_at"] + 60))
              if trial % 3 else int(rng.integers(0, len(payload))))
        damaged[at] = int(rng.integers(0, 256))
        try:
            Decoder(threads=1).decode(_with_rotn(bytes(damaged)))
        except FormatError as err:
            assert err.chunk == "ROTN"


def test_the_cli_flag_writes_mode_6_and_the_decode_matches(tmp_path):
    from csgs_cli.main import main
    from csgs_codec.codec.decoder import Decoder
    from csgs_codec.format import read_layers
    from tests.conftest import SAMPLE

    out = tmp_path / "d.csgs"
    assert main(["-q", "encode", str(SAMPLE), "-o", str(out), "--quality", "3",
                 "--no-hyperprior", "--rotation-steps", "anisotropy"]) == 0
    plain = tmp_path / "p.csgs"
    assert main(["-q", "encode", str(SAMPLE), "-o", str(plain), "--quality", "3",
                 "--no-hyperprior", "--uniform-steps"]) == 0
    def rotation_payload(path):
        container = read_layers(path.read_bytes(), layers={"color"})
        entry = next(e for e in container.toc if e.type == "ROTN")
        return bytes(container.payloads[entry.index])

    assert rotation_payload(out) != rotation_payload(plain)
    derived, uniform = (Decoder().decode(p.read_bytes()) for p in (out, plain))
    assert np.array_equal(derived.positions, uniform.positions)
    assert not np.array_equal(derived.rotations, uniform.rotations)
