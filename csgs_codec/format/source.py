"""Random-access byte sources for the reader: bytes, a path, a seekable binary file, or any
object that reads a byte range.

A source knows how many bytes it holds and returns exactly the range asked for, so the
reader can check every length against the bytes present before it reads or allocates.

**Range readers.** Any object with a ``size`` attribute (int: the bytes it holds) and a
method ``read_range(offset, size) -> bytes`` (exactly ``size`` bytes from ``offset``) is a
source, e.g. a client that fetches a file with HTTP range requests
(``Range: bytes=offset-(offset+size-1)``; ``size`` from ``Content-Length``). The decoder asks
for the header and TOC first, then one range per chunk frame it needs. A reader that returns
more bytes than asked is a careless caller (InputError); fewer, a truncated file
(FormatError).

**Files.** A path must name a regular file (:func:`csgs_codec.untrusted.open_regular`). A
binary file object is read by absolute offset (``os.pread`` for files of :func:`open`, else
seek + read under a lock per handle) and left at its position, so one handle can be decoded
again, or by several threads at once.
"""

from __future__ import annotations

import abc
import io
import os
import stat
import threading
import weakref
from typing import BinaryIO

from csgs_codec.errors import FormatError, InputError
from csgs_codec.untrusted import display_name, open_regular

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


#: Per-handle locks for file objects read by seek + read (see :func:`_handle_lock`).
_HANDLE_LOCKS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_HANDLE_LOCKS_GUARD = threading.Lock()
#: The lock of file objects that cannot be weakly referenced.
_SHARED_LOCK = threading.RLock()


def _handle_lock(handle) -> threading.RLock:
    """The one lock that every source over ``handle`` takes around its seek + read, so that
    sources in several threads sharing a handle never read at each other's positions."""
    with _HANDLE_LOCKS_GUARD:
        try:
            return _HANDLE_LOCKS.setdefault(handle, threading.RLock())
        except TypeError:  # not weakly referenceable
            return _SHARED_LOCK


def _os_file_descriptor(handle) -> int | None:
    """The descriptor to read ``handle`` with ``os.pread``: only for the binary file objects
    of :func:`open` (FileIO, or a buffered reader over one), whose bytes are the descriptor's;
    None for any other object (a GzipFile's ``fileno`` is its compressed file's)."""
    if not hasattr(os, "pread"):
        return None
    raw = handle if type(handle) is io.FileIO else None
    if type(handle) in (io.BufferedReader, io.BufferedRandom) and type(handle.raw) is io.FileIO:
        raw = handle.raw
    if raw is None:
        return None
    try:
        fd = raw.fileno()
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
    except (OSError, ValueError):
        return None
    return fd


def _refuse_unreadable(handle, name: str | None) -> None:
    """InputError unless ``handle`` reads bytes: text-mode and write-only files are refused."""
    if isinstance(handle, io.TextIOBase):
        raise InputError("source is a text-mode file; open it in binary mode ('rb')", file=name)
    readable = getattr(handle, "readable", None)
    try:
        if callable(readable) and not readable():
            raise InputError("source file is not readable (opened for writing only); open "
                             "it with 'rb'", file=name)
        probe = handle.read(0)
    except (OSError, ValueError) as exc:
        raise InputError(f"source file is not readable: {exc}", file=name) from None
    if isinstance(probe, str):
        raise InputError("source is a text-mode file; open it in binary mode ('rb')", file=name)


class _FileSource(ByteSource):
    """A file object read by absolute offset, its own position left where it was.

    Offsets are counted from the handle's position when the source is opened. Files of
    :func:`open` are read with ``os.pread``, which never moves the position; other objects
    with seek + read under one lock per handle, the position put back after each read.
    Either way the same handle can be decoded again, or from several threads at once.
    """

    def __init__(self, handle: BinaryIO, name: str | None, owned: bool) -> None:
        self._handle = handle
        self._owned = owned
        self._fd = _os_file_descriptor(handle)
        self._lock = _handle_lock(handle)
        _refuse_unreadable(handle, name)
        try:
            with self._lock:
                self._start = handle.tell()
                if self._fd is not None:
                    handle.flush()  # writes still buffered in a BufferedRandom reach the file
                    end = os.fstat(self._fd).st_size
                else:
                    end = handle.seek(0, io.SEEK_END)
                    handle.seek(self._start)
        except (OSError, ValueError, AttributeError) as exc:
            raise InputError(f"source is not a seekable binary file: {exc}", file=name) from None
        super().__init__(max(end - self._start, 0), name)

    def read(self, offset: int, n: int) -> bytes:
        at = self._start + offset
        try:
            data = self._pread(at, n) if self._fd is not None else self._seek_read(at, n)
        except (OSError, ValueError) as exc:
            raise FormatError(f"cannot read: {exc}", file=self.name, offset=offset) from None
        if isinstance(data, str):
            raise InputError("source is a text-mode file; open it in binary mode ('rb')",
                             file=self.name)
        if not isinstance(data, bytes | bytearray) or len(data) != n:
            got = len(data) if isinstance(data, bytes | bytearray) else 0
            raise FormatError(f"truncated: the file ended {n - got} bytes early",
                              file=self.name, offset=offset + got)
        return bytes(data)

    def _pread(self, at: int, n: int) -> bytes:
        """``n`` bytes at absolute position ``at`` (fewer at the end of the file)."""
        parts, got = [], 0
        while got < n:
            part = os.pread(self._fd, n - got, at + got)
            if not part:
                break
            parts.append(part)
            got += len(part)
        return b"".join(parts)

    def _seek_read(self, at: int, n: int):
        """``n`` bytes at absolute position ``at``, the handle's position restored."""
        with self._lock:
            before = self._handle.tell()
            self._handle.seek(at)
            try:
                return self._handle.read(n)
            finally:
                self._handle.seek(before)

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
        if not isinstance(data, bytes | bytearray | memoryview):
            raise InputError(f"the range reader returned {type(data).__name__}, not bytes, "
                             f"for a request of {n} bytes at byte {offset}", file=self.name)
        got = memoryview(data).nbytes
        if got > n:
            raise InputError(f"the range reader returned {got} bytes for a request of {n} at "
                             f"byte {offset}: too many (read_range(offset, size) must return "
                             "exactly size bytes)", file=self.name, offset=offset)
        if got < n:
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

    A path must name a regular file (see :func:`csgs_codec.untrusted.open_regular`). A file
    object is read from its current position, by absolute offset, and left at that
    position, so one handle can be decoded again or by several threads at once.

    Raises:
        InputError: the path cannot be opened, holds a NUL byte or is no regular file; the
            object is a text-mode, write-only or unseekable file.
    """
    if isinstance(source, bytes | bytearray | memoryview):
        return _BufferSource(source)
    if isinstance(source, str | os.PathLike):
        handle = open_regular(source)
        return _FileSource(handle, display_name(source), owned=True)
    if hasattr(source, "read_range"):
        return _RangeSource(source)
    if hasattr(source, "read") and hasattr(source, "seek"):
        name = getattr(source, "name", None)
        return _FileSource(source, name if isinstance(name, str) else None, owned=False)
    raise InputError(f"cannot read a .csgs container from {type(source).__name__}")
