"""Typed errors for csgs.

Every error the library raises on purpose is a :class:`CsgsError`. Each carries the context a
user needs to find the problem: the file, the property or chunk, and a byte offset where one
applies. The CLI prints ``str(error)`` on one line and exits with code 2.
"""

from __future__ import annotations

from pathlib import Path


class CsgsError(Exception):
    """Base class of every deliberate csgs error.

    Args:
        message: what is wrong, in one sentence.
        file: the file being read or written, if any.
        property: the PLY property or scene attribute concerned, if any.
        chunk: the four-character chunk type concerned, if any.
        offset: the byte offset in ``file`` (or in the byte string) where the problem is.
        index: the element index (e.g. the Gaussian) where the problem is.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        property: str | None = None,
        chunk: str | None = None,
        offset: int | None = None,
        index: int | None = None,
    ) -> None:
        self.message = message
        self.file = None if file is None else str(file)
        self.property = property
        self.chunk = chunk
        self.offset = offset
        self.index = index
        super().__init__(self.__str__())

    def __str__(self) -> str:
        where = []
        if self.file is not None:
            where.append(self.file)
        if self.chunk is not None:
            where.append(f"chunk '{self.chunk}'")
        if self.offset is not None:
            where.append(f"byte {self.offset}")
        if self.property is not None:
            where.append(f"property '{self.property}'")
        if self.index is not None:
            where.append(f"index {self.index}")
        prefix = ": ".join(where)
        return f"{prefix}: {self.message}" if prefix else self.message

    def __reduce__(self):
        # Keep keyword context when pickled (e.g. across process pools).
        return (_rebuild_error, (type(self), self.message, self.__dict__.copy()))


def _rebuild_error(cls, message, state):
    err = cls.__new__(cls)
    Exception.__init__(err, message)
    err.__dict__.update(state)
    return err


class InputError(CsgsError):
    """An input scene or file is malformed or holds values csgs cannot take (bad PLY, NaN, ...)."""


class FormatError(CsgsError):
    """A ``.csgs`` bitstream is malformed: bad magic, CRC, length, chunk or truncated data."""


class UnsupportedError(CsgsError):
    """The input is well formed but uses something csgs does not support (yet)."""


class ModelError(CsgsError):
    """A model cannot be exported or used deterministically (e.g. integer ranges could overflow)."""


class CsgsWarning(UserWarning):
    """A non-fatal notice about the input (e.g. dropped unknown PLY properties)."""


class DataLossWarning(CsgsWarning):
    """Input data was dropped (Gaussians with NaN/Inf under ``sanitize``, unknown PLY
    properties): the CLI prints it even with ``--quiet``."""


class FallbackWarning(CsgsWarning):
    """A fallback that changes the results took the place of missing input (the built-in
    segmenter for absent instance masks): the CLI prints it even with ``--quiet``."""


class CompoundedLossWarning(DataLossWarning):
    """The input was itself lossily coded (SPZ, SOG, .splat, ...): encoding it again adds a
    second quantization to the first. Shown even with ``--quiet``."""


def require_type(value, expected: type | tuple[type, ...], what: str, hint: str = "") -> None:
    """Raise :class:`InputError` naming ``what`` unless ``value`` is an ``expected`` instance.

    The message says which type was expected and which was given (a file name given where a
    scene object belongs gets ``hint``, e.g. how to read the file first), instead of the
    AttributeError the first attribute access on the wrong object would raise.
    """
    if isinstance(value, expected):
        return
    names = " or ".join(t.__name__ for t in (expected if isinstance(expected, tuple)
                                             else (expected,)))
    given = "None" if value is None else _article(type(value).__name__)
    if isinstance(value, str | bytes | Path) and hint:
        given += f" ({hint})"
    raise InputError(f"expected {_article(names)}, got {given}", property=what)


def _article(noun: str) -> str:
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"
