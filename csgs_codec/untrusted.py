"""Reading input csgs did not write: regular files only, bounded reads, JSON of bounded depth.

Every scene, camera and ``.csgs`` reader opens its files here, so one set of rules holds:

* Only regular files are read (a symlink to one is followed). A device (``/dev/zero``), a
  FIFO, a socket or a directory is refused with :class:`~csgs_codec.errors.InputError` naming
  the file, before anything is read: such a "file" has no size, so reading it whole could
  run until memory is exhausted, and opening a FIFO could wait forever.
* A regular file's size, taken when it is opened, bounds every whole-file read; where a
  reader has a limit of its own (camera files, SOG members, MLP files) a larger file is
  refused before it is read.
* JSON is parsed from bytes with :func:`load_json`, which turns every failure (bad UTF-8,
  bad syntax, nesting deep enough to exhaust Python's recursion limit) into a typed error
  naming the file, and refuses documents nested deeper than :data:`MAX_JSON_DEPTH`.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import BinaryIO

from csgs_codec.errors import CsgsError, InputError

#: Deepest JSON nesting (arrays and objects) accepted. Real glTF, SOG meta.json and camera
#: files nest fewer than 10 levels; a bound well below Python's recursion limit keeps later
#: code that walks or prints the document (repr, numpy) from recursing too deep.
MAX_JSON_DEPTH = 64

#: Flags for opening a path that is then checked to be a regular file: O_NONBLOCK so that
#: opening a FIFO without a writer returns at once instead of waiting; O_NOCTTY so that a
#: terminal device never becomes the controlling terminal.
_OPEN_FLAGS = (os.O_RDONLY | getattr(os, "O_BINARY", 0) | getattr(os, "O_NONBLOCK", 0)
               | getattr(os, "O_NOCTTY", 0))


def display_name(path: str | os.PathLike | bytes) -> str:
    """``path`` as text for messages, with NUL bytes shown as ``\\0``."""
    text = os.fsdecode(path) if isinstance(path, bytes | os.PathLike) else str(path)
    return text.replace("\0", "\\0")


def _kind(mode: int) -> str:
    """What a non-regular file is, in words, from its ``st_mode``."""
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def _refuse_non_regular(mode: int, path) -> None:
    if not stat.S_ISREG(mode):
        raise InputError(f"{_kind(mode)}, not a regular file: csgs reads only regular files "
                         "(a symlink to one is fine)", file=display_name(path))


def _check_path(path) -> str | bytes:
    """``os.fspath(path)``; InputError when it holds a NUL byte (no file name can)."""
    name = os.fspath(path)
    if ("\0" in name) if isinstance(name, str) else (b"\0" in name):
        raise InputError("the path contains a NUL byte, which no file name can hold",
                         file=display_name(name))
    return name


def refuse_non_regular(path: str | os.PathLike, *, directory_ok: bool = False) -> None:
    """InputError naming ``path`` unless it is a regular file (or, with ``directory_ok``, a
    directory), after following symlinks: for readers that take a file or a folder and must
    refuse a device or FIFO before looking inside. Opens nothing."""
    name = _check_path(path)
    try:
        mode = os.stat(name).st_mode
    except OSError as exc:
        raise _os_error(exc, name) from None
    if not (directory_ok and stat.S_ISDIR(mode)):
        _refuse_non_regular(mode, name)


def _os_error(exc: OSError, path) -> InputError:
    """The InputError for an OSError met opening or reading ``path``."""
    if isinstance(exc, FileNotFoundError):
        return InputError("file not found", file=display_name(path))
    return InputError(f"cannot read: {exc.strerror or exc}", file=display_name(path))


def open_regular(path: str | os.PathLike) -> BinaryIO:
    """``path`` opened for binary reading (a ``BufferedReader``; the caller closes it),
    provided it is a regular file after following symlinks.

    Raises:
        InputError: the path holds a NUL byte, is missing or unreadable, or names a directory,
            device, FIFO or socket (the message says which), naming the file.
    """
    name = _check_path(path)
    try:
        _refuse_non_regular(os.stat(name).st_mode, name)  # before opening a device at all
        fd = os.open(name, _OPEN_FLAGS)
    except OSError as exc:
        raise _os_error(exc, name) from None
    try:
        # Checked again on the open descriptor: the path may have changed since the stat.
        _refuse_non_regular(os.fstat(fd).st_mode, name)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: str | os.PathLike, limit: int | None = None, *,
                 what: str = "this file") -> bytes:
    """All bytes of the regular file at ``path``: at most its size when opened, and at most
    ``limit`` bytes where given.

    Args:
        path: the file.
        limit: the largest size accepted, bytes (None: the file's own size bounds the read).
        what: what the file is, for the message when it is too large ("a camera file").

    Raises:
        InputError: see :func:`open_regular`; or the file is larger than ``limit``.
    """
    with open_regular(path) as handle:
        try:
            size = os.fstat(handle.fileno()).st_size
            if limit is not None and size > limit:
                raise InputError(f"{size:,} bytes, more than the {limit:,} csgs reads for "
                                 f"{what}", file=display_name(path))
            # A file that grows while being read is read up to its size when opened.
            data = handle.read(size)
        except OSError as exc:
            raise _os_error(exc, path) from None
    return data


def json_depth_exceeds(document, limit: int = MAX_JSON_DEPTH) -> bool:
    """True when ``document`` (parsed JSON) nests lists and dicts deeper than ``limit``;
    walked without recursion."""
    stack = [(document, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict):
            children = node.values()
        elif isinstance(node, list):
            children = node
        else:
            continue
        if depth > limit:
            return True
        stack.extend((child, depth + 1) for child in children
                     if isinstance(child, dict | list))
    return False


def load_json(data: bytes | str, *, file: str | Path | None = None, what: str = "JSON",
              error: type[CsgsError] = InputError, **where):
    """The document in ``data``, JSON from an untrusted source (UTF-8 bytes or text).

    Args:
        data: the JSON text.
        file: the file it came from, for messages.
        what: what the text is, for messages ("the JSON chunk", "meta.json").
        error: the typed error to raise (InputError for input files).
        where: more context for the error (offset=..., property=...).

    Raises:
        ``error``: not UTF-8, not JSON (with line and column), or nested deeper than
            :data:`MAX_JSON_DEPTH` (also when so deep that the parser itself gives up).
    """
    try:
        document = json.loads(data)
    except RecursionError:
        document = None
        too_deep = True
    except UnicodeDecodeError as exc:
        raise error(f"{what} is not UTF-8 text (byte {exc.start})", file=file,
                    **where) from None
    except json.JSONDecodeError as exc:
        raise error(f"{what} is not JSON: {exc.msg} at line {exc.lineno} column "
                    f"{exc.colno}", file=file, **where) from None
    except ValueError as exc:  # e.g. an integer literal longer than Python converts
        raise error(f"{what} is not JSON: {exc}", file=file, **where) from None
    else:
        too_deep = json_depth_exceeds(document)
    if too_deep:
        raise error(f"{what} nests arrays or objects more than {MAX_JSON_DEPTH} levels deep",
                    file=file, **where)
    return document



#: The signature every .npy file starts with (numpy's format, NEP 1).
NPY_MAGIC = b"\x93NUMPY"
#: Largest .npy header read (numpy writes headers padded to 64 bytes; 64 KiB is generous).
MAX_NPY_HEADER = 1 << 16
_KIND_WORDS = {"b": "booleans", "i": "integers", "u": "integers", "f": "floats"}


def read_npy(path: str | os.PathLike, limit: int, *, what: str = "this file",
             kinds: str = "biuf"):
    """The array in the ``.npy`` file ``path``, read without pickles and without trusting
    its header: the header's shape and dtype are checked against the file's size before
    any array is made, so a 64-byte file claiming 10^10 values allocates nothing.

    Args:
        path: the file.
        limit: the largest file size accepted, bytes.
        what: what the file is, for messages ("a query embedding").
        kinds: numpy dtype kinds accepted (default bool, signed, unsigned, float).

    Returns:
        The array, in the header's shape and dtype (a writable copy).

    Raises:
        InputError: naming the file: not a .npy (an .npz, empty, other bytes), a malformed
            header, a dtype of another kind or with objects, a shape that is not whole numbers,
            or a size that does not match the header.
    """
    import ast

    import numpy as np

    name = display_name(path)
    data = read_regular(path, limit, what=what)
    if data.startswith(b"PK\x03\x04"):
        raise InputError(f"an .npz archive, not a .npy file: {what} is one array saved with "
                         "numpy.save", file=name)
    if not data.startswith(NPY_MAGIC) or len(data) < 10:
        found = "an empty file" if not data else "no .npy signature"
        raise InputError(f"not a .npy file ({found}): {what} is one array saved with "
                         "numpy.save", file=name)
    major = data[6]
    width = 2 if major == 1 else 4 if major in (2, 3) else None
    if width is None:
        raise InputError(f".npy format version {major} is not supported (1-3 are)", file=name)
    start = 8 + width
    length = int.from_bytes(data[8:start], "little")
    if length > MAX_NPY_HEADER or start + length > len(data):
        raise InputError(f".npy header of {length:,} bytes does not fit the file", file=name)
    try:
        header = ast.literal_eval(data[start:start + length].decode("latin1"))
        shape, fortran, descr = header["shape"], header["fortran_order"], header["descr"]
        dtype = np.dtype(descr)
    except (ValueError, SyntaxError, TypeError, KeyError, MemoryError, RecursionError):
        raise InputError("malformed .npy header", file=name) from None
    if (not isinstance(shape, tuple) or len(shape) > 32
            or not all(type(side) is int and side >= 0 for side in shape)):
        raise InputError(f".npy shape must be whole numbers >= 0, got {shape!r}", file=name)
    if dtype.hasobject or dtype.kind not in kinds or dtype.fields is not None:
        wanted = " or ".join(dict.fromkeys(_KIND_WORDS[k] for k in kinds))
        raise InputError(f"holds {dtype} values; {what} holds {wanted}", file=name)
    count = 1
    for side in shape:
        count *= side
    body = len(data) - start - length
    if count * dtype.itemsize != body:
        raise InputError(f".npy header says {shape} {dtype} ({count * dtype.itemsize:,} bytes) "
                         f"but the file holds {body:,} bytes of values", file=name)
    values = np.frombuffer(data, dtype=dtype, count=count, offset=start + length)
    return values.reshape(shape, order="F" if fortran is True else "C").copy()
