"""Write spec/vectors/invalid/: damaged .csgs files a decoder must refuse, with a manifest.

    python -m tests.fuzz.invalid_vectors --write [--out spec/vectors/invalid]

Two kinds of vector:

- fuzz mutants: for each mutation operator, the first input of campaign 0 that applies only
  that operator to a valid seed (CRCs repaired) and that the decoder refuses, preferring
  refusals by a chunk decoder; likewise for the payload operators on anchor-scene seeds
  (``fuzz_anchor_*``); they pin that these kinds of damage keep failing cleanly;
- hand-made: a 290-byte file that declares 2^18 identical Gaussians (every channel constant,
  one grid point repeated): a decompression bomb (it once decoded to a 262,144-Gaussian scene
  with a heap peak ~10,000 times its size) that the decoder must refuse before allocating.

manifest.json lists every file with what it tests, the error class expected, the chunk the
decoder named when the vector was written (informative), its size and SHA-256, and for a
vector the decoder does not yet refuse, ``xfail`` with the reason. Vectors are never deleted;
this script rewrites the folder only when asked with ``--write``.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from csgs_codec.codec.encoder import Encoder
from csgs_codec.errors import CsgsError
from csgs_codec.format import encode_varint
from csgs_codec.scene.gaussian_scene import GaussianScene
from tests.conformance import VECTORS_DIR
from tests.fuzz.campaign import mutant_at
from tests.fuzz.container_edit import build, split_chunks
from tests.fuzz.oracle import decode, error_stage
from tests.fuzz.seeds import build_seeds

INVALID_DIR = VECTORS_DIR / "invalid"
SCAN_INPUTS = 6000
MAX_VECTOR_BYTES = 32768
#: Operators whose refusals are also kept for anchor-scene seeds (their payload parsers).
ANCHOR_OPERATORS = ("payload_bit_flip", "payload_byte_set", "payload_resize", "payload_varint",
                    "payload_word", "payload_swap", "chunk_swap", "truncate")
BOMB_GAUSSIANS = 1 << 18


def identical_scene(count: int) -> GaussianScene:
    """``count`` identical SH-0 Gaussians (every channel constant)."""
    ones = np.ones((count, 3), np.float32)
    return GaussianScene(positions=ones * 0.5, sh_dc=ones * 0.2,
                         sh_rest=np.zeros((count, 0, 3), np.float32),
                         opacity=np.ones(count, np.float32), scales=ones * -3.0,
                         rotations=np.tile(np.array([1, 0, 0, 0], np.float32), (count, 1)))


def _leading_varint_length(data: bytes) -> int:
    return next(i for i, b in enumerate(data) if b < 0x80) + 1


def count_bomb(count: int) -> bytes:
    """A valid file for 5 identical Gaussians with every count field raised to ``count``.

    Each count is the leading varint of its payload (SCNE, every float stream); GEOM holds its
    point count after a 2-byte header and the repeat list "one point, count - 2 extra copies";
    ROTN starts with its categorical stream as a length-prefixed byte string.
    """
    small = Encoder(quality=5).encode(identical_scene(5))
    n = encode_varint(count)
    chunks = []
    for chunk in split_chunks(small):
        p = chunk.payload
        if chunk.type == b"GEOM":  # version, bits, points 5, distinct 1, repeats 1, gap 0, extra 3
            assert p[2:7] == b"\x05\x01\x01\x00\x03", p.hex()
            p = p[:2] + n + b"\x01\x01\x00" + encode_varint(count - 2) + p[7:]
        elif chunk.type == b"ROTN":
            head = _leading_varint_length(p)
            stream = p[head:head + p[0]]
            stream = n + stream[_leading_varint_length(stream):]
            rest = p[head + p[0]:]
            p = encode_varint(len(stream)) + stream + n + rest[_leading_varint_length(rest):]
        else:
            p = n + p[_leading_varint_length(p):]
        chunks.append(dataclasses.replace(chunk, payload=p))
    return build(chunks)


def _refusal(data: bytes):
    try:
        decode(data)
    except CsgsError as err:
        return err
    return None


def _is_anchor_seed(name: str) -> bool:
    return name.startswith("vector:anchors")


def fuzz_vectors(seeds) -> list[tuple[str, bytes, str, CsgsError]]:
    """(name, bytes, description, error) for the first clean refusal of each operator, on
    Gaussian-scene seeds, and of each operator in :data:`ANCHOR_OPERATORS` on anchor seeds."""
    valid = {seed.name for seed in seeds if _refusal(seed.data) is None}
    chosen: dict[str, tuple] = {}
    for index in range(SCAN_INPUTS):
        mutant = mutant_at(seeds, index)
        ops = [op for op in mutant.operators if op != "crc_repaired"]
        if (len(ops) != 1 or len(mutant.data) > MAX_VECTOR_BYTES or mutant.seed not in valid
                or ("crc_repaired" not in mutant.operators and ops[0] != "crc_lie")):
            continue
        op = ops[0].split(":")[0]
        if _is_anchor_seed(mutant.seed):
            if op not in ANCHOR_OPERATORS:
                continue
            op = f"anchor_{op}"
        err = _refusal(mutant.data)
        if err is None:
            continue
        deeper = error_stage(err) == "payload"
        if op in chosen and (chosen[op][3] or not deeper):
            continue
        text = (f"fuzz input {index} of campaign 0: {' + '.join(mutant.operators)} "
                f"applied to seed {mutant.seed}")
        chosen[op] = (mutant.data, text, err, deeper)
    return [(op, data, text, err) for op, (data, text, err, _) in sorted(chosen.items())]


def _entry(name: str, data: bytes, tests: str, err: CsgsError | None, expected: str,
           xfail: str | None = None) -> dict:
    entry = {"file": name, "tests": tests, "expected_error": expected,
             "chunk_when_written": None if err is None else err.chunk,
             "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    if xfail:
        entry["xfail"] = xfail
    return entry


def write(out_dir: Path) -> list[dict]:
    """Write the vectors and manifest.json into ``out_dir``; returns the manifest entries."""
    out_dir.mkdir(parents=True, exist_ok=True)
    entries = []
    bomb = count_bomb(BOMB_GAUSSIANS)
    (out_dir / "gaussian_count_bomb.csgs").write_bytes(bomb)
    entries.append(_entry("gaussian_count_bomb.csgs", bomb,
                          f"a {len(bomb)}-byte file declaring {BOMB_GAUSSIANS} identical "
                          "Gaussians must be refused before the decoder allocates them",
                          _refusal(bomb), "FormatError"))
    for op, data, text, err in fuzz_vectors(build_seeds()):
        name = f"fuzz_{op}.csgs"
        (out_dir / name).write_bytes(data)
        entries.append(_entry(name, data, text, err, type(err).__name__))
    manifest = {"schema": "csgs-invalid-vectors/1",
                "description": "Damaged .csgs files; decoding with layers color,semantic must "
                               "raise expected_error (never another exception), within 64 x "
                               "the file size + 4 MiB of heap.",
                "vectors": entries}
    (out_dir / "manifest.json").write_text(json.dumps(manifest, indent=2) + "\n")
    return entries


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="(re)write the folder")
    parser.add_argument("--out", type=Path, default=INVALID_DIR)
    args = parser.parse_args()
    if not args.write:
        parser.error("nothing to do: pass --write to write the invalid vectors")
    for entry in write(args.out):
        print(f"{entry['file']}: {entry['expected_error']} ({entry['bytes']} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
