""".npy inputs (query embeddings, mask embeddings, selection masks) are read without pickles
and without trusting their header (issue #52, item 2): an .npz, an empty file, a header that
claims more values than the file holds, a shape that is not whole numbers, and bytes that are
no .npy at all each end in one InputError line naming the file, exit 2."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.untrusted import read_npy
from tests.codec.helpers import random_scene


def _npy_with_header(header: str, body: bytes = b"") -> bytes:
    text = header.encode("latin1")
    pad = 128 - 10 - len(text) - 1
    return b"\x93NUMPY\x01\x00" + (len(text) + pad + 1).to_bytes(2, "little") + text \
        + b" " * pad + b"\n" + body


def _npz(path):
    with open(path, "wb") as fh:  # np.savez would add '.npz' to a name
        np.savez(fh, x=np.ones(3))


BAD_FILES = {
    "npz": (lambda p: _npz(p), "an .npz archive"),
    "empty": (lambda p: p.write_bytes(b""), "empty file"),
    "huge header": (lambda p: p.write_bytes(_npy_with_header(
        "{'descr': '<f4', 'fortran_order': False, 'shape': (10000000000,), }")),
        "40,000,000,000 bytes"),
    "bool shape": (lambda p: p.write_bytes(_npy_with_header(
        "{'descr': '<f4', 'fortran_order': False, 'shape': (True, 8), }", bytes(32))),
        "shape must be whole numbers"),
    "text": (lambda p: p.write_text("a text file, not numpy"), "no .npy signature"),
    "pickle": (lambda p: np.save(p, np.array([{}], dtype=object), allow_pickle=True),
               "holds object values"),
    "short body": (lambda p: p.write_bytes(_npy_with_header(
        "{'descr': '<f8', 'fortran_order': False, 'shape': (3,), }", bytes(16))),
        "holds 16 bytes of values"),
}


@pytest.mark.parametrize("kind", sorted(BAD_FILES))
def test_query_embedding_that_is_no_sane_npy_exits_2(tmp_path, capsys, kind):
    make, fragment = BAD_FILES[kind]
    scene = tmp_path / "scene.ply"
    write_ply(random_scene(16, sh_degree=0), scene)
    query = tmp_path / "q.npy"
    make(query)
    assert main(["query", str(scene), "--embedding", str(query), "-q"]) == 2
    err = capsys.readouterr().err
    assert fragment in err and str(query) in err
    assert err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize("kind", sorted(BAD_FILES))
def test_read_npy_names_the_file(tmp_path, kind):
    make, fragment = BAD_FILES[kind]
    path = tmp_path / "x.npy"
    make(path)
    with pytest.raises(InputError, match=fragment) as err:
        read_npy(path, 1 << 20, what="a test array")
    assert err.value.file == str(path)


@pytest.mark.parametrize("order", ["C", "F"])
def test_read_npy_returns_what_numpy_saved(tmp_path, order):
    array = np.asarray(np.arange(12, dtype=np.int16).reshape(3, 4), order=order)
    path = tmp_path / "a.npy"
    np.save(path, array)
    back = read_npy(path, 1 << 20)
    assert back.dtype == np.int16 and back.shape == (3, 4)
    np.testing.assert_array_equal(back, array)


def test_a_selection_mask_of_integers_is_refused_by_kind(tmp_path, capsys):
    scene = tmp_path / "scene.ply"
    write_ply(random_scene(16, sh_degree=0), scene)
    mask = tmp_path / "m.npy"
    np.save(mask, np.ones(16, dtype=np.int64))
    assert main(["view", str(scene), "--select-mask", str(mask), "--screenshot",
                 str(tmp_path / "s.png"), "-q"]) == 2
    assert "holds int64 values; a selection mask holds booleans" in capsys.readouterr().err
