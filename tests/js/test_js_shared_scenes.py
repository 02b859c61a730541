"""The JavaScript receiver decodes real scenes, encoded by today's encoder at qualities 1, 5,
9 and 12 (the near-lossless end) with its default settings, to the Python decoder's arrays
(issue #18's acceptance).

The default suite runs the SH-3 capture kept in benchmarks/data (8.2k Gaussians: every SH
band, per-scene steps, the color hyperprior) at the default quality, sharing its encode with
the browser test; ``-m slow`` runs it at all four and adds the two small SH-3 captures of
../shared (real_sh3/) and its five shared scenes (up to 248k Gaussians). Skipped when node
(or, for those, ../shared) is absent.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks._js_receiver import node_executable, run_js, scene_hashes
from csgs_codec import Decoder, Encoder, read_ply
from csgs_codec.decisions.presets import DEFAULT_QUALITY
from tests.conftest import SHARED_DATA, shared_path

pytestmark = pytest.mark.skipif(node_executable() is None,
                                reason="node (Node.js >= 18) is not on PATH")

SMALL = ["real_sh3/fruit_drops.ply", "real_sh3/leica_sofort_top8192.ply"]
LARGE = [f"scenes/{name}.ply" for name in ("donut", "biker", "guitar", "plant", "playbot")]
QUALITIES = (1, 5, 9, 12)


#: The SH-3 capture the repository keeps (benchmarks/data, CC0): run where ../shared is absent.
REPO_SH3 = Path(__file__).resolve().parents[2] / "benchmarks" / "data" / "yashica_t4_top8192.ply"


def _check(relative: str, tmp_path, default_encoding, qualities=QUALITIES) -> None:
    source = REPO_SH3 if relative == "repo" else shared_path(*relative.split("/"))
    scene = read_ply(source)
    files, expected = [], []
    for quality in qualities:
        # The default quality is the run's shared default encode (tests/conftest.py).
        result = (default_encoding(source)[1] if quality == DEFAULT_QUALITY
                  else Encoder(quality=quality).encode_with_report(scene))
        data = result.data
        path = tmp_path / f"q{quality}.csgs"
        path.write_bytes(data)
        decoded = Decoder().decode(data)
        assert decoded.equals(result.reconstruction), f"{relative} q{quality}"
        files.append(path)
        expected.append((len(decoded), scene_hashes(decoded)))
    for threads in (1, 2):
        for quality, js, (count, arrays) in zip(qualities, run_js(files, threads=threads),
                                                expected):
            what = f"{relative} q{quality}, {threads} thread(s)"
            assert js["ok"], f"{what}: {js}"
            assert js["count"] == count, what
            assert js["arrays"] == arrays, f"{what}: decoded arrays differ"


def test_the_repository_sh3_capture_decodes_as_in_python_at_the_default_quality(
        tmp_path, default_encoding):
    # Each encode probes its step allocation for seconds: the default quality only here.
    _check("repo", tmp_path, default_encoding, (DEFAULT_QUALITY,))


@pytest.mark.slow
@pytest.mark.parametrize("relative", SMALL)
def test_the_small_scenes_decode_as_in_python_at_every_quality(relative, tmp_path,
                                                               default_encoding):
    _check(relative, tmp_path, default_encoding)


@pytest.mark.slow
def test_the_repository_sh3_capture_decodes_as_in_python_at_every_quality(tmp_path,
                                                                           default_encoding):
    _check("repo", tmp_path, default_encoding)


@pytest.mark.slow
@pytest.mark.parametrize("relative", LARGE)
def test_shared_scenes_decode_as_in_python(relative, tmp_path, default_encoding):
    _check(relative, tmp_path, default_encoding)


def test_the_scene_lists_name_files_that_exist():
    if not SHARED_DATA.exists():
        pytest.skip(f"shared data not present: {SHARED_DATA}")
    assert all((SHARED_DATA / r).is_file() for r in SMALL + LARGE)
