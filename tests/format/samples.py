"""Shared sample containers and instrumented file objects for the format tests."""

from __future__ import annotations

import io

from csgs_codec.format import Chunk, Layer


def sample_chunks() -> list[Chunk]:
    """A small three-layer scene: several chunks per layer, two tiles, multi-byte varints."""
    return [
        Chunk("fill", Layer.BASE, b"scene header stand-in"),
        Chunk("fill", Layer.BASE, bytes(range(200)), tile=0),
        Chunk("fill", Layer.COLOR, b"color tile 0" * 12, tile=0),
        Chunk("fill", Layer.COLOR, b"color tile 1", tile=1),
        Chunk("fill", Layer.SEMANTIC, b"semantic tile 0" * 3, tile=0),
        Chunk("fill", Layer.SEMANTIC, b"", tile=1),
    ]


class GuardedFile(io.RawIOBase):
    """A seekable read-only file over ``data`` that fails any read touching a forbidden range.

    ``forbidden`` is a list of [start, end) byte ranges. Every read request is recorded in
    ``reads`` as (offset, n); ``read(-1)`` (read everything) is refused too.
    """

    def __init__(self, data: bytes, forbidden: list[tuple[int, int]]) -> None:
        super().__init__()
        self._data = data
        self._pos = 0
        self.forbidden = forbidden
        self.reads: list[tuple[int, int]] = []

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._pos, io.SEEK_END: len(self._data)}[whence]
        self._pos = base + offset
        return self._pos

    def tell(self) -> int:
        return self._pos

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0:
            raise AssertionError("read of the whole file requested")
        self.reads.append((self._pos, n))
        for start, end in self.forbidden:
            if self._pos < end and self._pos + n > start:
                raise AssertionError(f"read of [{self._pos}, {self._pos + n}) touches the "
                                     f"forbidden range [{start}, {end})")
        out = self._data[self._pos:self._pos + n]
        self._pos += len(out)
        return out

    def readinto(self, buffer) -> int:
        data = self.read(len(buffer))
        buffer[:len(data)] = data
        return len(data)
