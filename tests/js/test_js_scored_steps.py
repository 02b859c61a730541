"""The JavaScript receiver decodes rotation channels with scored steps (FORMAT §12.8, the
default encoder's) to the Python decoder's arrays, on one and two threads, with and without
the color hyperprior, and rejects a bad cell table or ``coding`` byte where Python does.
Skipped without ``node``."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks._js_receiver import node_executable, run_js, scene_hashes
from csgs_codec import Decoder, Encoder
from csgs_codec.errors import FormatError
from tests.codec.helpers import random_scene
from tests.codec.test_scored_steps import RESULT, _rotn, _rotn_fields, _with_rotn

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")


@pytest.mark.parametrize("threads", [1, 2])
def test_scored_steps_decode_in_javascript(tmp_path, threads):
    scene = random_scene(5000, sh_degree=1, seed=8)
    path = tmp_path / "scored.csgs"
    # Step allocation is not the subject (tests/codec/test_step_allocation.py): off, 8 s less.
    path.write_bytes(Encoder(quality=5, hyperprior=False, step_allocation=False).encode(scene))
    assert _rotn_fields(_rotn(path.read_bytes()))["scored"]
    [js] = run_js([path], threads=threads)
    assert js["ok"], js
    assert js["arrays"] == scene_hashes(Decoder().decode(path.read_bytes()))


def test_scored_steps_with_the_hyperprior_decode_in_javascript(tmp_path):
    from csgs_codec.decisions.color_prior_choice import PriorFitPolicy
    from csgs_codec.model.color_hyperprior import ColorFitSettings

    policy = PriorFitPolicy(ColorFitSettings(steps=60), min_gaussians=0, keep_when_larger=True)
    path = tmp_path / "scored_prior.csgs"
    path.write_bytes(Encoder(quality=4, prior_fit=policy).encode(
        random_scene(5000, sh_degree=0, seed=12)))
    assert _rotn_fields(_rotn(path.read_bytes()))["scored"]
    [js] = run_js([path], threads=2)
    assert js["ok"], js
    assert js["arrays"] == scene_hashes(Decoder().decode(path.read_bytes()))


@pytest.mark.parametrize("damage", ["nan_weight", "unsorted_thresholds", "bin_count_9",
                                    "reserved_coding_bit", "scored_histogram"])
def test_bad_cell_tables_are_rejected_where_python_rejects_them(tmp_path, damage):
    payload = bytearray(_rotn(RESULT.data))
    fields = _rotn_fields(bytes(payload))
    if damage == "nan_weight":
        at = fields["weights_at"] + 20
        payload[at:at + 4] = np.float32(np.nan).tobytes()
    elif damage == "unsorted_thresholds":
        at = fields["thresholds_u_at"]
        payload[at:at + 8] = payload[at + 4:at + 8] + payload[at:at + 4]
    elif damage == "bin_count_9":
        payload[fields["bins_u_at"]] = 9
    elif damage == "reserved_coding_bit":
        payload[fields["coding_at"]] |= 0x04
    else:  # scored steps with a histogram table source
        payload[fields["coding_at"]] = (payload[fields["coding_at"]] & ~0x03) | 0x02
    path = tmp_path / "bad.csgs"
    path.write_bytes(_with_rotn(bytes(payload)))
    with pytest.raises(FormatError) as info:
        Decoder().decode(path.read_bytes())
    for threads in (1, 2):
        [js] = run_js([path], threads=threads)
        assert not js["ok"] and js["error"] == "FormatError", js
        assert (js["chunk"], js["offset"]) == (info.value.chunk, info.value.offset)
