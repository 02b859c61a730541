"""A file object given as a source is read by absolute offset and left where it was: one
handle decodes again and again, and from several threads at once, to the same scene."""

from __future__ import annotations

import io
import threading
from pathlib import Path

import numpy as np
import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.format.source import open_source

REPO = Path(__file__).resolve().parents[2]
VECTOR = REPO / "spec" / "vectors" / "scenes" / "three_points_sh3_q9.csgs"
THREADS = 4


def _arrays(scene) -> dict[str, np.ndarray]:
    return {name: getattr(scene, name) for name in ("positions", "sh_dc", "sh_rest", "opacity",
                                                   "scales", "rotations")}


def _assert_same(a, b) -> None:
    left, right = _arrays(a), _arrays(b)
    for name in left:
        np.testing.assert_array_equal(left[name], right[name], err_msg=name)


def _handles(tmp_path: Path):
    """(label, opener) pairs: a real file (pread path) and in-memory objects (seek path)."""
    prefixed = tmp_path / "prefixed.bin"
    prefixed.write_bytes(b"junk" * 5 + VECTOR.read_bytes())

    def at_offset():
        handle = open(prefixed, "rb")  # noqa: SIM115 - closed by the test
        handle.seek(20)
        return handle

    return {
        "file": lambda: open(VECTOR, "rb"),
        "unbuffered file": lambda: open(VECTOR, "rb", buffering=0),
        "file at an offset": at_offset,
        "BytesIO": lambda: io.BytesIO(VECTOR.read_bytes()),
    }


@pytest.mark.parametrize("kind", ["file", "unbuffered file", "file at an offset", "BytesIO"])
def test_one_handle_decodes_twice_in_a_row(tmp_path, kind):
    expected = Decoder().decode(VECTOR)
    with _handles(tmp_path)[kind]() as handle:
        start = handle.tell()
        first = Decoder().decode(handle)
        assert handle.tell() == start
        second = Decoder().decode(handle)
        assert handle.tell() == start
    _assert_same(first, expected)
    _assert_same(second, expected)


@pytest.mark.parametrize("kind", ["file", "file at an offset", "BytesIO"])
def test_threads_sharing_one_handle_decode_the_same_scene(tmp_path, kind):
    expected = Decoder().decode(VECTOR)
    results, errors = [None] * THREADS, []
    barrier = threading.Barrier(THREADS)
    with _handles(tmp_path)[kind]() as handle:

        def work(slot: int) -> None:
            barrier.wait()
            try:
                for _ in range(3):
                    results[slot] = Decoder().decode(handle)
            except Exception as exc:  # noqa: BLE001 - reported by the assertion below
                errors.append(f"{type(exc).__name__}: {exc}")

        threads = [threading.Thread(target=work, args=(i,)) for i in range(THREADS)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert errors == []
    for scene in results:
        _assert_same(scene, expected)


def test_interleaved_reads_of_two_sources_on_one_handle_stay_at_their_offsets():
    data = bytes(range(256)) * 4
    handle = io.BytesIO(data)
    a = open_source(handle)
    handle.seek(100)
    b = open_source(handle)
    assert (a.size, b.size) == (1024, 924)
    assert a.read(10, 3) == data[10:13]
    assert b.read(10, 3) == data[110:113]
    assert a.read(0, 2) == data[0:2]
    assert handle.tell() == 100
