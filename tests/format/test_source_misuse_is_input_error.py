"""Sources a careless caller gets wrong are InputErrors that say what is wrong: a text-mode
file, a path holding a NUL byte, a range reader that returns more bytes than asked."""

from __future__ import annotations

from pathlib import Path

import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.errors import InputError
from csgs_codec.format.source import open_source

REPO = Path(__file__).resolve().parents[2]
VECTOR = REPO / "spec" / "vectors" / "scenes" / "three_points_sh3_q9.csgs"


def test_a_text_mode_file_is_an_input_error_saying_binary_mode():
    with open(VECTOR) as handle:
        with pytest.raises(InputError, match=r"text-mode file; open it in binary mode \('rb'\)"):
            Decoder().decode(handle)
        with pytest.raises(InputError, match="text-mode") as info:
            open_source(handle)
    assert info.value.file == str(VECTOR)


@pytest.mark.parametrize("path", ["scene\0.csgs", Path("scene\0.csgs")])
def test_a_path_with_a_nul_byte_is_an_input_error(path):
    with pytest.raises(InputError, match="NUL byte") as info:
        Decoder().decode(path)
    assert info.value.file == "scene\\0.csgs"


class _Generous:
    """A range reader that returns ``extra`` bytes more than asked for."""

    def __init__(self, data: bytes, extra: int) -> None:
        self.data, self.extra, self.size = data, extra, len(data)

    def read_range(self, offset: int, size: int) -> bytes:
        return self.data[offset:offset + size + self.extra]


def test_a_range_reader_returning_too_many_bytes_is_an_input_error():
    with pytest.raises(InputError, match="the range reader returned 116 bytes for a request "
                                         "of 16 at byte 0: too many") as info:
        Decoder().decode(_Generous(VECTOR.read_bytes(), 100))
    assert info.value.offset == 0


def test_a_range_reader_returning_exact_ranges_still_decodes():
    assert len(Decoder().decode(_Generous(VECTOR.read_bytes(), 0))) == 3


def test_a_write_only_file_is_an_input_error(tmp_path):
    with open(tmp_path / "out.bin", "wb") as handle:
        handle.write(VECTOR.read_bytes())
        with pytest.raises(InputError, match="not readable"):
            open_source(handle)
