"""Semantic channel names (FORMAT §12.16), both directions: the name list SEMF, SEMC and
the anchor codec's ASEM carry, and the rule every name keeps."""

from __future__ import annotations

import re

from csgs_codec.format.primitives import ByteReader, ByteWriter

MAX_SEMANTIC_CHANNELS = 256
#: A float stream's channel_count is one byte (FORMAT §12.8): SEMF carries at most 255.
MAX_FLOAT_STREAM_CHANNELS = 255
#: Longest semantic channel name, in UTF-8 bytes (FORMAT §12.16).
MAX_NAME_BYTES = 256


def names_to_bytes(out: ByteWriter, names: tuple[str, ...]) -> None:
    """Append varint S and S UTF-8 byte strings."""
    out.varint(len(names))
    for name in names:
        out.byte_string(name.encode("utf-8"))


#: A semantic channel name (FORMAT §12.16): a PLY property name a 3DGS reader keeps as a
#: semantic channel (the prefix), ASCII letters, digits and underscores only, so that it
#: cannot break a PLY header or collide with a standard 3DGS property.
SEMANTIC_NAME = re.compile(r"(sem_|ins_feat_)[A-Za-z0-9_]+")
SEMANTIC_NAME_RULE = ("sem_ or ins_feat_ followed by one or more ASCII letters, digits or "
                      "underscores, each name once")


def semantic_name_problem(name: str, earlier) -> str | None:
    """Why ``name`` cannot be a semantic channel name after the names ``earlier`` (a
    collection), or None when it can (:data:`SEMANTIC_NAME_RULE`)."""
    if not SEMANTIC_NAME.fullmatch(name):
        return (f"semantic channel name {name!r} is not a PLY-safe semantic identifier "
                f"(names are {SEMANTIC_NAME_RULE})")
    if len(name) > MAX_NAME_BYTES:
        return f"semantic channel name is {len(name)} bytes long, over {MAX_NAME_BYTES}"
    if name in earlier:
        return f"semantic channel name {name!r} appears twice"
    return None


def names_from_bytes(r: ByteReader, maximum: int) -> tuple[str, ...]:
    """Read what :func:`names_to_bytes` wrote (at most ``maximum`` names of <= 256 bytes):
    the semantic channel names of SEMF and ASEM, each checked against
    :data:`SEMANTIC_NAME_RULE` (FormatError at the offending name)."""
    count = r.varint("channel_count", maximum=maximum)
    names = []
    for _ in range(count):
        at = r.offset
        raw = r.byte_string("channel_name", maximum=MAX_NAME_BYTES)
        try:
            name = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise r.error("channel name is not UTF-8") from None
        problem = semantic_name_problem(name, names)
        if problem:
            raise r.error(problem, at)
        names.append(name)
    return tuple(names)
