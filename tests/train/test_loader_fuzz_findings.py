"""The inputs the loader fuzz campaign (benchmarks/fuzz_loaders.py) found crashing or
over its memory bound, each now a typed error naming the file and field, exit 2 from the CLI
with one line."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.train.datasets import load_dataset
from csgs_codec.train.image_files import read_mask
from tests.fuzz.loader_seeds import loader_seeds
from tests.heap_peak import heap_peak


def _capture(tmp_path, layout: str):
    seed = next(s for s in loader_seeds() if s.format == layout)
    root = tmp_path / layout
    for name, data in seed.files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(data)
    return root


def _exits_2_naming(tmp_path, capsys, root, *fragments: str) -> None:
    out = tmp_path / "x.csgs"
    assert main(["train", str(root), "-o", str(out), "--iterations", "1", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    for fragment in fragments:
        assert fragment in err
    assert not out.exists()


@pytest.mark.parametrize("header", [
    "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 17), ",  # numpy: TokenError
    "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 18446744073709551616), }",
    "{'descr': '<c16', 'fortran_order': False, 'shape': (3, 17), }",
])
def test_a_hostile_poses_bounds_header_is_a_typed_error(tmp_path, capsys, header):
    root = _capture(tmp_path, "llff")
    path = root / "poses_bounds.npy"
    body = np.load(path).tobytes()
    encoded = header.encode("latin1")
    path.write_bytes(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(encoded)) + encoded + body)
    with pytest.raises(InputError, match="poses_bounds.npy"):
        load_dataset(root, segment_missing=False)
    _exits_2_naming(tmp_path, capsys, root, "poses_bounds.npy")


@pytest.mark.parametrize("key", ["fx", "position"])
def test_a_json_integer_past_a_float_is_a_typed_error_naming_the_field(tmp_path, capsys, key):
    root = _capture(tmp_path, "inria")
    entries = json.loads((root / "cameras.json").read_text())
    entries[1][key] = 10 ** 400 if key == "fx" else [1, 10 ** 400, 2]
    (root / "cameras.json").write_text(json.dumps(entries))
    with pytest.raises(InputError, match=rf"cameras.json.*\[1\]\.{key}"):
        load_dataset(root, segment_missing=False)
    _exits_2_naming(tmp_path, capsys, root, "cameras.json", f"[1].{key}")


def test_a_png_chunk_longer_than_its_file_is_refused_before_pillow_reads_it(tmp_path, capsys):
    root = _capture(tmp_path, "transforms")
    mask = root / "masks" / "view_002.png"
    data = bytearray(mask.read_bytes())
    assert data[37:41] == b"IDAT"
    data[33:37] = struct.pack(">I", 1 << 29)  # the IDAT claims 512 MiB
    mask.write_bytes(bytes(data))
    with heap_peak() as peak, pytest.raises(InputError, match="'IDAT' at byte 33"):
        read_mask(mask)
    assert peak.bytes < 4 << 20  # Pillow allocated the 512 MiB it was promised
    _exits_2_naming(tmp_path, capsys, root, "view_002.png", "IDAT")
