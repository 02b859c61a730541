"""A SEMC payload whose prototype rows repeat is invalid (spec/FORMAT.md §12.23; issue #52,
item 14): two instances with one feature cannot be told apart (a click or a query picks one
of them at random, and the encoder refuses to write the decoded scene again). Both decoders
refuse it at the prototypes' offset."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from benchmarks._js_receiver import REPO, node_executable
from csgs_codec.chunks.semantic_codebook import read_codebook, write_codebook
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter

NAMES = ("ins_feat_0", "ins_feat_1")
AT = 500
IDS = np.array([0, 1, 2, 1])


def _payload(prototypes) -> bytes:
    out = ByteWriter()
    write_codebook(out, NAMES, np.asarray(prototypes, np.float32), IDS,
                   np.ones((len(prototypes), 3), np.float32))
    return out.getvalue()


REPEATED = [[1.0, 2.0], [0.5, 0.5], [1.0, 2.0]]
DISTINCT = [[1.0, 2.0], [0.5, 0.5], [-0.0, 2.0]]
# Prototypes start after version (1), the names (1 + 2 x (1 + 10)), instance_count (1) and
# prototype_format (1).
PROTOTYPES_AT = AT + 1 + 1 + 2 * 11 + 1 + 1


def test_repeated_prototype_rows_are_a_format_error_at_their_offset():
    with pytest.raises(FormatError, match="two prototype rows are equal") as err:
        read_codebook(ByteReader(_payload(REPEATED), base_offset=AT, chunk="SEMC"), 4, 256)
    assert err.value.offset == PROTOTYPES_AT and err.value.chunk == "SEMC"


def test_rows_that_differ_in_any_bit_are_distinct():
    names, features, table = read_codebook(
        ByteReader(_payload(DISTINCT), base_offset=AT, chunk="SEMC"), 4, 256)
    assert names == NAMES and len(table.prototypes) == 3
    np.testing.assert_array_equal(features, np.asarray(DISTINCT, np.float32)[IDS])


@pytest.mark.skipif(node_executable() is None, reason="node is not on PATH")
def test_the_javascript_receiver_refuses_them_at_the_same_offset():
    cases = [{"kind": "SEMC", "hex": _payload(p).hex(), "offset": AT, "max": 4}
             for p in (REPEATED, DISTINCT)]
    done = subprocess.run([node_executable(), str(REPO / "tests" / "js" / "payloads.mjs")],
                          input=json.dumps(cases), capture_output=True, text=True,
                          timeout=120, check=True)
    repeated, distinct = (json.loads(line) for line in done.stdout.splitlines())
    assert repeated == {"ok": False, "chunk": "SEMC", "offset": PROTOTYPES_AT}
    assert distinct == {"ok": True, "names": list(NAMES)}
