"""Every file in spec/vectors/invalid/ is refused with the error class its manifest names,
within the fuzzing memory bound (64 x file size + 4 MiB of heap). Files are decoded as the
fuzz oracle decodes them: anchor scenes with AnchorDecoder, others with Decoder."""

from __future__ import annotations

import hashlib
import json

import pytest

from csgs_codec.errors import CsgsError
from tests.fuzz.invalid_vectors import INVALID_DIR
from tests.fuzz.oracle import decode, memory_bound
from tests.heap_peak import heap_peak

MANIFEST = json.loads((INVALID_DIR / "manifest.json").read_text())
ENTRIES = MANIFEST["vectors"]


def _params():
    for entry in ENTRIES:
        marks = [pytest.mark.xfail(strict=True, reason=entry["xfail"])] if "xfail" in entry else []
        yield pytest.param(entry, id=entry["file"], marks=marks)


def test_manifest_lists_every_file_in_the_folder():
    on_disk = {p.name for p in INVALID_DIR.glob("*.csgs")}
    assert on_disk == {entry["file"] for entry in ENTRIES}
    assert all(entry["expected_error"] for entry in ENTRIES)


@pytest.mark.parametrize("entry", list(_params()))
def test_invalid_vector_is_refused_with_its_error_class(entry):
    data = (INVALID_DIR / entry["file"]).read_bytes()
    assert (len(data), hashlib.sha256(data).hexdigest()) == (entry["bytes"], entry["sha256"])
    with heap_peak() as peak, pytest.raises(CsgsError) as info:
        decode(data)
    assert type(info.value).__name__ == entry["expected_error"]
    assert peak.bytes <= memory_bound(len(data))
