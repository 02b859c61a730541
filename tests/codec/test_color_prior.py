"""The color hyperprior (CHYP and the channels coded with its tables): rate only, exact
decode, clear errors."""

from __future__ import annotations

import contextlib
import random
from dataclasses import replace

import numpy as np
import pytest

from csgs_codec.chunks.color_prior import (
    ColorPrior,
    color_prior_payload,
    keep_outputs,
    prior_from_bytes,
)
from csgs_codec.chunks.scene_header import SceneHeader
from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.encoder import Encoder
from csgs_codec.decisions.color_prior_choice import PriorFitPolicy
from csgs_codec.errors import FormatError
from csgs_codec.format import Chunk, read_layers, write_container
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.model.color_hyperprior import ColorFitSettings
from tests.codec.helpers import random_scene, steps_of
from tests.conftest import SAMPLE

SHORT_FIT = ColorFitSettings(steps=150, batch=512)
NAMES = ["dc", "opacity", "scale", "rot"]


@pytest.fixture(scope="module")
def donut():
    return read_ply(SAMPLE)


@pytest.fixture(scope="module")
def small_pair(donut):
    """(with prior, without prior) encodes of 3,000 donut Gaussians at quality 4."""
    scene = donut.subset(np.arange(3000))
    policy = PriorFitPolicy(SHORT_FIT, min_gaussians=0, keep_when_larger=True)
    with_prior = Encoder(quality=4, prior_fit=policy).encode_with_report(scene)
    without = Encoder(quality=4, hyperprior=False).encode_with_report(scene)
    return with_prior, without


def chunks_of(data: bytes) -> list[Chunk]:
    container = read_layers(data, layers={"color", "semantic"})
    return [Chunk(e.type, e.layer, bytes(container.payloads[e.index]), e.tile)
            for e in container.toc]


def rebuilt(data: bytes, replace_with: dict[str, bytes] | None = None,
            drop: str | None = None) -> bytes:
    chunks = [c if c.type not in (replace_with or {}) else
              Chunk(c.type, c.layer, replace_with[c.type]) for c in chunks_of(data)
              if c.type != drop]
    return write_container(chunks)


def chyp_prior(data: bytes):
    """(CHYP payload, its parsed ColorPrior, the grid bits) of an encoded file."""
    chunks = {c.type: c.payload for c in chunks_of(data)}
    bits = max(SceneHeader.from_bytes(chunks["SCNE"], 0).grid_bits, 1)
    payload = chunks["CHYP"]
    return payload, prior_from_bytes(payload, base_offset=0, names=NAMES, pos_bits=bits), bits


def _assert_same_scene(a, b):
    for name, value in a.attributes().items():
        other = b.attributes()[name]
        assert (value is None and other is None) or np.array_equal(value, other), name


def test_prior_changes_the_rate_only(small_pair):
    with_prior, without = small_pair
    assert "CHYP" in with_prior.stream_bytes and "CHYP" not in without.stream_bytes
    decoded = Decoder().decode(with_prior.data)
    _assert_same_scene(decoded, with_prior.reconstruction)
    _assert_same_scene(decoded, without.reconstruction)


def test_prior_decodes_identically_with_one_and_two_threads(small_pair):
    data = small_pair[0].data
    _assert_same_scene(Decoder(threads=1).decode(data), Decoder(threads=2).decode(data))


def test_prior_makes_a_real_scene_smaller(donut):
    policy = PriorFitPolicy(ColorFitSettings(steps=300))
    with_prior = Encoder(quality=5, prior_fit=policy).encode_with_report(donut)
    without = Encoder(quality=5, hyperprior=False).encode(donut)
    assert "CHYP" in with_prior.stream_bytes
    assert len(with_prior.data) < 0.98 * len(without)
    _assert_same_scene(Decoder().decode(with_prior.data), with_prior.reconstruction)


def test_small_scenes_and_fast_encodes_skip_the_fit(donut):
    assert "CHYP" not in Encoder(quality=5).encode_with_report(random_scene(500)).stream_bytes
    fast = Encoder(quality=5, fast=True).encode_with_report(donut.subset(np.arange(9000)))
    assert "CHYP" not in fast.stream_bytes


def test_keep_outputs_leaves_the_kept_outputs_unchanged(small_pair):
    _, prior, bits = chyp_prior(small_pair[0].data)
    cells = np.random.default_rng(0).integers(0, 1 << bits, size=(200, 3))
    m = int(prior.mask.sum())
    keep = np.arange(m) % 2 == 0
    full = prior.net.forward(cells)
    kept = keep_outputs(prior, keep)
    assert np.array_equal(kept.net.forward(cells), full[:, np.concatenate([keep, keep])])
    assert kept.mask.sum() == keep.sum() and not (kept.mask & ~prior.mask).any()


def test_a_mode_5_channel_without_chyp_names_its_chunk(small_pair):
    with pytest.raises(FormatError, match="color hyperprior") as info:
        Decoder().decode(rebuilt(small_pair[0].data, drop="CHYP"))
    assert info.value.chunk in ("SHDC", "OPAC", "SCAL", "ROTN")


@pytest.mark.parametrize("field, offset, value, message", [
    ("version", 0, 2, "version 2"),
    ("channel_count", 1, 11, "covers 11 channels"),
    ("stray mask bit", 3, 0x80, "beyond the channel count"),
])
def test_bad_chyp_fields_are_format_errors(small_pair, field, offset, value, message):
    payload = bytearray(next(c.payload for c in chunks_of(small_pair[0].data)
                             if c.type == "CHYP"))
    assert payload[1] == 10  # dc 3 + opacity 1 + scale 3 + rot 3 channels
    payload[offset] = value if field != "stray mask bit" else payload[offset] | value
    with pytest.raises(FormatError, match=message) as info:
        Decoder().decode(rebuilt(small_pair[0].data, {"CHYP": bytes(payload)}))
    assert info.value.chunk == "CHYP"


def test_scale_outputs_outside_the_table_family_are_refused(small_pair):
    payload, prior, bits = chyp_prior(small_pair[0].data)
    hi = prior.net.out_hi.copy()
    hi[-1] = 64
    bad = ColorPrior(prior.mask, replace(prior.net, out_hi=hi))
    with pytest.raises(FormatError, match="scale"):
        prior_from_bytes(color_prior_payload(bad), base_offset=0, names=NAMES, pos_bits=bits)
    with pytest.raises(FormatError, match="pos_bits"):
        prior_from_bytes(payload, base_offset=0, names=NAMES, pos_bits=bits + 1)


def test_damaged_chyp_only_raises_format_error(small_pair):
    data = small_pair[0].data
    payload = next(c.payload for c in chunks_of(data) if c.type == "CHYP")
    rng = random.Random(3)
    for _ in range(60):
        damaged = bytearray(payload)
        for _ in range(rng.randint(1, 3)):
            damaged[rng.randrange(len(damaged))] = rng.randrange(256)
        with contextlib.suppress(FormatError):
            Decoder().decode(rebuilt(data, {"CHYP": bytes(damaged)}))
    with pytest.raises(FormatError):
        Decoder().decode(rebuilt(data, {"CHYP": payload[: len(payload) // 2]}))


def test_fit_progress_counts_the_training_steps(donut):
    calls = []
    policy = PriorFitPolicy(ColorFitSettings(steps=120, batch=256), min_gaussians=0)
    Encoder(quality=4, prior_fit=policy,
            progress=steps_of("color hyperprior", calls)).encode(donut.subset(np.arange(2000)))
    assert calls == [(50, 120), (100, 120), (120, 120)]


def test_a_fit_run_in_parts_equals_one_run(donut):
    from csgs_codec.chunks.color_prior import MEAN_BITS, MEAN_LIMIT
    from csgs_codec.entropy.intnet_bytes import intnet_to_bytes
    from csgs_codec.model.color_hyperprior import ColorPriorFit

    rng = np.random.default_rng(4)
    cells = rng.integers(0, 1 << 10, (3000, 3))
    residuals = np.column_stack([cells[:, 0] // 64 + rng.integers(-2, 3, 3000),
                                 rng.integers(-5, 6, 3000)])
    settings = ColorFitSettings(steps=80, batch=256)

    def fit():
        return ColorPriorFit(cells, 10, residuals, settings, mean_bits=MEAN_BITS,
                              mean_limit=MEAN_LIMIT)

    whole, parts = fit(), fit()
    whole.train(80)
    parts.train(30)
    parts.train(80)
    assert intnet_to_bytes(whole.export()) == intnet_to_bytes(parts.export())


def test_a_trial_that_saves_little_stops_the_fit():
    calls = []
    scene = random_scene(6000, sh_degree=0, seed=5)  # attributes independent of position
    policy = PriorFitPolicy(ColorFitSettings(steps=600, batch=256), min_gaussians=0)
    result = Encoder(quality=5, prior_fit=policy,
                     progress=steps_of("color hyperprior", calls, lambda done, total: done)
                     ).encode_with_report(scene)
    assert "CHYP" not in result.stream_bytes
    assert calls[-1] == 300


def test_the_default_encoder_runs_the_full_fit_and_keeps_the_prior(donut):
    """The encoder as users run it (no test settings): the whole 1,500-step fit on the
    sample, the prior kept, and the file decodes to the reconstruction."""
    from csgs_codec.decisions.color_prior_choice import DEFAULT_PRIOR_FIT

    steps = []
    encoder = Encoder(progress=steps_of("color hyperprior", steps))
    assert encoder.config.prior_fit is DEFAULT_PRIOR_FIT and DEFAULT_PRIOR_FIT.settings is None
    result = encoder.encode_with_report(donut)
    assert steps[-1] == (ColorFitSettings().steps, ColorFitSettings().steps)
    assert "CHYP" in result.stream_bytes
    _assert_same_scene(Decoder().decode(result.data), result.reconstruction)


def test_prior_fit_must_be_a_policy():
    from csgs_codec.errors import InputError

    with pytest.raises(InputError, match="prior_fit"):
        Encoder(prior_fit={"steps": 10})
