"""The JavaScript receiver decodes rotation channels with derived steps (mode 6, FORMAT §12.8)
to the Python decoder's arrays, on one and two threads, with and without the color
hyperprior, and rejects a bad class table where Python does. Skipped without ``node``."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks._js_receiver import node_executable, run_js, scene_hashes
from csgs_codec import Decoder, Encoder
from csgs_codec.errors import FormatError
from tests.codec.helpers import random_scene
from tests.codec.test_derived_steps import _chunks, _rotn_fields, _with_rotn

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")


def _encode(tmp_path: Path, name: str, **options) -> Path:
    scene = random_scene(options.pop("count", 3000), sh_degree=1, seed=5)
    path = tmp_path / f"{name}.csgs"
    options.setdefault("step_allocation", False)  # not the subject here: 4 s less
    path.write_bytes(Encoder(quality=5, rotation_steps="anisotropy", **options).encode(scene))
    return path


@pytest.mark.parametrize("threads", [1, 2])
def test_derived_steps_decode_in_javascript(tmp_path, threads):
    path = _encode(tmp_path, "derived", hyperprior=False)
    assert _rotn_fields(_chunks(path.read_bytes())[-1].payload)["mode"] == 6
    [js] = run_js([path], threads=threads)
    assert js["ok"], js
    assert js["arrays"] == scene_hashes(Decoder().decode(path.read_bytes()))


@pytest.mark.slow
def test_derived_steps_with_the_hyperprior_decode_in_javascript(tmp_path):
    path = _encode(tmp_path, "derived_prior", count=9000)
    [js] = run_js([path], threads=2)
    assert js["ok"], js
    assert js["arrays"] == scene_hashes(Decoder().decode(path.read_bytes()))


@pytest.mark.parametrize("threads", [1, 2])
def test_bad_threshold_is_rejected_where_python_rejects_it(tmp_path, threads):
    from tests.codec.test_derived_steps import RESULT

    payload = bytearray(_chunks(RESULT.data)[-1].payload)
    at = _rotn_fields(bytes(payload))["thresholds_at"]
    payload[at:at + 4] = bytes([0, 0, 0xC0, 0x7F])  # NaN
    path = tmp_path / "bad.csgs"
    path.write_bytes(_with_rotn(bytes(payload)))
    with pytest.raises(FormatError) as info:
        Decoder().decode(path.read_bytes())
    [js] = run_js([path], threads=threads)
    assert not js["ok"] and js["error"] == "FormatError", js
    assert (js["chunk"], js["offset"]) == (info.value.chunk, info.value.offset)
