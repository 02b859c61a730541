"""The body of an ASCII PLY: one row per line, an element's rows after the previous one's.

Read strictly (:func:`read_ascii_vertex_columns`): the body holds exactly the rows the
header's counts add up to; every row of every element holds the values its properties need
(a list property: its length, then that many entries); every vertex value is a PLY number
(C's strtod syntax, or nan/inf) and a value of an integer property (char, uchar, short,
ushort, int, uint) is a whole number in its type's range. Anything else is an
:class:`~csgs_codec.errors.InputError` naming the element, row and property.
"""

from __future__ import annotations

import contextlib
import re

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_header import PlyElement, PlyHeader

#: A PLY ASCII number as C's strtod reads it (decimal), or nan/inf: Python's float() also
#: takes "1_000", which no PLY writer means.
ASCII_NUMBER = re.compile(rb"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)",
                          re.IGNORECASE)
#: A list length: a whole number, optionally signed "+".
_COUNT = re.compile(rb"\+?\d{1,9}")
#: numpy type code of each PLY integer type -> (PLY name, smallest, largest value).
INTEGER_TYPES = {code: (name, int(np.iinfo(code).min), int(np.iinfo(code).max))
                 for code, name in (("i1", "char"), ("u1", "uchar"), ("i2", "short"),
                                    ("u2", "ushort"), ("i4", "int"), ("u4", "uint"))}


def read_ascii_vertex_columns(data: bytes, header: PlyHeader, vertex: PlyElement,
                              source: str | None) -> dict[str, np.ndarray]:
    """The vertex columns of the ASCII PLY ``data`` ({property: (N,) float64}), after
    checking every element's rows (see the module docstring).

    Raises:
        InputError: fewer or more rows than declared, a row with the wrong number of
            values, a value that is no number or does not fit its integer type.
    """
    body = data[header.header_bytes:]
    skip = 0
    for el in header.elements:
        if el is vertex:
            break
        skip += el.count
    total = sum(el.count for el in header.elements)
    # Each value takes at least two bytes (a digit and a separator): a cheap bound on the
    # count before splitting anything.
    if (skip + vertex.count * len(vertex.properties)) * 2 > len(body) + 1:
        raise InputError(f"element 'vertex' declares {vertex.count} rows but the body has only "
                         f"{len(body)} bytes (truncated body or wrong count)", file=source,
                         offset=header.header_bytes)
    if total > len(body) + 1:  # every row but the last ends with a newline
        raise InputError(f"the elements declare {total} rows but the body has only "
                         f"{len(body)} bytes (truncated body or wrong count)", file=source,
                         offset=header.header_bytes)
    lines = body.split(b"\n", total)
    _check_row_count(lines, header, source, len(data))
    if len(lines) > total and lines[total].strip():
        extra = lines[total]
        raise InputError("data follows the last row the header declares (a header count "
                         "smaller than the body, or trailing data)", file=source,
                         offset=len(data) - len(extra))
    columns, start = {}, 0
    for el in header.elements:
        rows = lines[start:start + el.count]
        if el is vertex:
            columns = _vertex_columns(rows, vertex, source)
        else:
            _check_element_rows(rows, el, source)
        start += el.count
    return columns


def _check_row_count(lines: list[bytes], header: PlyHeader, source: str | None,
                     end: int) -> None:
    """InputError naming the element and row of the first row the body lacks, where
    ``lines`` is the body split at its first (total rows) newlines."""
    total = sum(el.count for el in header.elements)
    present = len(lines)
    if present > total:
        return
    # Blank pieces at the end (the one after a final newline, empty lines) are no rows.
    while present and not lines[present - 1].strip():
        present -= 1
    if present >= total:
        return
    first = 0
    for el in header.elements:
        if present < first + el.count:
            raise InputError(f"element '{el.name}' declares {el.count} rows, the body has "
                             f"{present - first} (truncated body or wrong count)",
                             file=source, offset=end, index=present - first)
        first += el.count


def _vertex_columns(rows: list[bytes], vertex: PlyElement, source: str | None
                    ) -> dict[str, np.ndarray]:
    """{property: (N,) float64} of the vertex ``rows``, each holding one value per
    property, each a number that fits its property's type."""
    n_props = len(vertex.properties)
    tokens = []
    for i, row in enumerate(rows):
        values = row.split()
        if len(values) != n_props:
            raise InputError(f"vertex row {i} has {len(values)} values, expected {n_props}",
                             file=source, index=i)
        tokens += values
    values = _numbers(tokens, vertex, source).reshape(len(rows), n_props)
    _check_integer_ranges(values, tokens, vertex, source)
    return {p.name: values[:, i] for i, p in enumerate(vertex.properties)}


def _numbers(tokens: list[bytes], vertex: PlyElement, source: str | None) -> np.ndarray:
    """The ASCII ``tokens`` (rows of len(properties) values) as float64; InputError naming
    the row and property of the first token that is not a number."""
    n_props = len(vertex.properties)
    if b"_" not in b"".join(tokens):
        with contextlib.suppress(ValueError):
            return np.array(tokens, dtype=np.float64)
    for at, token in enumerate(tokens):
        if not ASCII_NUMBER.fullmatch(token):
            row, col = divmod(at, n_props)
            raise InputError(f"non-numeric value {token.decode('ascii', 'replace')!r}",
                             file=source, property=vertex.properties[col].name, index=row)
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError as exc:
        raise InputError(f"non-numeric value in vertex data ({exc})", file=source) from None


def _check_integer_ranges(values: np.ndarray, tokens: list[bytes], vertex: PlyElement,
                          source: str | None) -> None:
    """InputError naming row and property of the first value of an integer property that is
    not a whole number in its type's range; ``values`` (N, properties) float64."""
    n_props = len(vertex.properties)
    for col, prop in enumerate(vertex.properties):
        if prop.type_code not in INTEGER_TYPES:
            continue
        name, low, high = INTEGER_TYPES[prop.type_code]
        column = values[:, col]
        with np.errstate(invalid="ignore"):
            whole = np.isfinite(column) & (column == np.floor(column))
            bad = ~whole | (column < low) | (column > high)
        if not bad.any():
            continue
        row = int(np.flatnonzero(bad)[0])
        text = tokens[row * n_props + col].decode("ascii", "replace")
        problem = ("is not a whole number" if not whole[row] else "does not fit")
        raise InputError(f"vertex row {row}: {text} {problem} property type {name} "
                         f"({low}..{high})", file=source, property=prop.name, index=row)


def _check_element_rows(rows: list[bytes], el: PlyElement, source: str | None) -> None:
    """InputError naming the row of ``el`` (not the vertices) whose values do not match its
    properties: one per scalar, a list's length then that many entries."""
    for i, row in enumerate(rows):
        values = row.split()
        need = _values_needed(values, el, i, source)
        if len(values) != need:
            raise InputError(f"{el.name} row {i} has {len(values)} values, its properties "
                             f"need {need}", file=source, index=i)


def _values_needed(values: list[bytes], el: PlyElement, row: int, source: str | None) -> int:
    """How many values a row of ``el`` whose tokens are ``values`` must hold (as many as
    can be told: a list whose length is missing counts as its length alone)."""
    need = 0
    for prop in el.properties:
        if prop.type_code != "list":
            need += 1
            continue
        if need >= len(values):
            return need + 1
        length = values[need]
        if not _COUNT.fullmatch(length):
            raise InputError(f"{el.name} row {row}: list length "
                             f"{length.decode('ascii', 'replace')!r} of property "
                             f"'{prop.name}' is not a count", file=source, property=prop.name,
                             index=row)
        need += 1 + int(length)
    return need
