"""Decoding with one or two threads gives the same scene and the same first error."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_codec import Decoder, Encoder
from csgs_codec.errors import FormatError, InputError
from csgs_codec.interchange.ply_io import read_ply
from tests.codec.helpers import SHORT_PRIOR_FIT
from tests.conftest import SAMPLE

FIELDS = ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations")


@pytest.fixture(scope="module")
def data():
    return Encoder(quality=4, prior_fit=SHORT_PRIOR_FIT).encode(read_ply(SAMPLE))


def test_one_and_two_threads_decode_identically(data):
    one = Decoder(threads=1).decode(data)
    two = Decoder(threads=2).decode(data)
    for name in FIELDS:
        a, b = getattr(one, name), getattr(two, name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name


def test_the_same_error_is_raised_whatever_the_thread_count(data):
    """Two truncated streams in a well-formed container: the first in stream order (SHDC
    before SCAL) is reported, with one thread or two."""
    import dataclasses

    from tests.fuzz.container_edit import build, split_chunks

    chunks = [dataclasses.replace(c, payload=c.payload[:3]) if c.type in (b"SHDC", b"SCAL")
              else c for c in split_chunks(data)]
    damaged = build(chunks)
    messages = []
    for threads in (1, 2):
        with pytest.raises(FormatError) as error:
            Decoder(threads=threads).decode(damaged)
        messages.append(str(error.value))
    assert messages[0] == messages[1] and "SHDC" in messages[0]


def test_a_thread_count_below_one_is_refused():
    with pytest.raises(InputError, match="threads"):
        Decoder(threads=0)
    assert np.isfinite(Decoder().threads)
