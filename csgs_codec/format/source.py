"""Random-access byte sources for the reader: bytes, a path, a seekable binary file, or any
object that reads a byte range.

A source knows how many bytes it holds and returns exactly the range asked for, so the
reader can check every length against the bytes present before it reads or allocates.

**Range readers.** Any object with a ``size`` attribute (int: the bytes it holds) and a
method ``read_range(offset, size) -> bytes`` (exactly ``size`` bytes from ``offset``) is a
source, e.g. a client that fetches a file with HTTP range requests
(``Range: bytes=offset-(offset+size-1)``; ``size`` from ``Content-Length``). The decoder asks
for the header and TOC first, then one range per chunk frame it needs.
"""

from __future__ import annotations

import abc
import io
import os
from pathlib import Path
from typing import BinaryIO

from csgs_codec.errors import FormatError, InputError

SourceLike = bytes | bytearray | memoryview | str | os.PathLike | BinaryIO


class ByteSource(abc.ABC):
    """A random-access view of a container.

    Offsets are relative to the container's first byte (for a file object: its position
    when the source was opened). ``size`` is the number of bytes available from there.
    """

    def __init__(self, size: int, name: str | None) -> None:
        self.size = size
        self.name = name

    @abc.abstractmethod
    def read(self, offset: int, n: int) -> bytes:
        """Exactly ``n`` bytes at ``offset``; the caller has checked the range against size."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the file or buffer this source holds (a caller's own file stays open)."""


class _BufferSource(ByteSource):
    def __init__(self, data: bytes | bytearray | memoryview) -> None:
        self._view = memoryview(data).cast("B")
        super().__init__(len(self._view), None)

    def read(self, offset: int, n: int) -> bytes:
        return bytes(self._view[offset:offset + n])

    def close(self) -> None:
        self._view.release()


class _FileSource(ByteSource):
    def __init__(self, handle: BinaryIO, name: str | None, owned: bool) -> None:
        self._handle = handle
        self._owned = owned
        try:
            self._start = handle.tell()
            end = handle.seek(0, io.SEEK_END)
        except (OSError, ValueError, AttributeError) as exc:
            raise InputError(f"source is not a seekable binary file: {exc}", file=name) from None
        super().__init__(max(end - self._start, 0), name)

    def read(self, offset: int, n: int) -> bytes:
        try:
            self._handle.seek(self._start + offset)
            data = self._handle.read(n)
        except OSError as exc:
            raise FormatError(f"cannot read: {exc}", file=self.name, offset=offset) from None
        if isinstance(data, str):
            raise InputError("source is a text-mode file; open it in binary mode ('rb')",
                             file=self.name)
        if not isinstance(data, bytes | bytearray) or len(data) != n:
            got = len(data) if isinstance(data, bytes | bytearray) else 0
            raise FormatError(f"truncated: the file ended {n - got} bytes early",
                              file=self.name, offset=offset + got)
        return bytes(data)

    def close(self) -> None:
        if self._owned:
            self._handle.close()


class _RangeSource(ByteSource):
    def __init__(self, reader) -> None:
        size = getattr(reader, "size", None)
        if isinstance(size, bool) or not isinstance(size, int) or size < 0:
            raise InputError(f"a range reader needs an integer 'size' attribute, got {size!r}")
        name = getattr(reader, "name", None)
        self._reader = reader
        super().__init__(size, name if isinstance(name, str) else None)

    def read(self, offset: int, n: int) -> bytes:
        try:
            data = self._reader.read_range(offset, n)
        except OSError as exc:
            raise FormatError(f"cannot read: {exc}", file=self.name, offset=offset) from None
        if not isinstance(data, bytes | bytearray | memoryview) or len(data) != n:
            got = len(data) if isinstance(data, bytes | bytearray | memoryview) else 0
            raise FormatError(f"truncated: the range reader returned {got} of {n} bytes",
                              file=self.name, offset=offset + got)
        return bytes(data)

    def close(self) -> None:
        pass


class CountingSource(ByteSource):
    """A source that passes reads on to ``inner`` and counts the bytes they return
    (:attr:`bytes_read`)."""

    def __init__(self, inner: ByteSource) -> None:
        super().__init__(inner.size, inner.name)
        self.inner = inner
        self.bytes_read = 0

    def read(self, offset: int, n: int) -> bytes:
        data = self.inner.read(offset, n)
        self.bytes_read += len(data)
        return data

    def close(self) -> None:
        self.inner.close()


def open_source(source: SourceLike) -> ByteSource:
    """A :class:`ByteSource` over ``source`` (bytes-like, a path, a seekable binary file, or
    a range reader: see the module docstring).

    Raises:
        InputError: the path cannot be opened or the object is not a seekable binary file.
    """
    if isinstance(source, bytes | bytearray | memoryview):
        return _BufferSource(source)
    if isinstance(source, str | os.PathLike):
        path = Path(source)
        if path.is_dir():
            raise InputError("is a directory", file=path)
        try:
            handle = open(path, "rb")  # noqa: SIM115 - closed by ByteSource.close
        except OSError as exc:
            raise InputError(f"cannot open: {exc.strerror or exc}", file=path) from None
        return _FileSource(handle, str(path), owned=True)
    if hasattr(source, "read_range"):
        return _RangeSource(source)
    if hasattr(source, "read") and hasattr(source, "seek"):
        name = getattr(source, "name", None)
        return _FileSource(source, name if isinstance(name, str) else None, owned=False)
    raise InputError(f"cannot read a .csgs container from {type(source).__name__}")
