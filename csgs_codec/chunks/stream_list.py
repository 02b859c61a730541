"""The framing ACRM and AFEA share (FORMAT §17.5, §17.8): a varint count, then that many
length-prefixed byte strings (one CARM network, or one feature group's residual stream,
each)."""

from __future__ import annotations

from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Most strings a list may hold (one per CARM group; ``carm_groups`` is at most 64).
MAX_STRINGS = 64


def stream_list_payload(strings: list[bytes]) -> bytes:
    """The payload of ``strings``: varint count, then each as varint length + bytes."""
    out = ByteWriter()
    out.varint(len(strings))
    for data in strings:
        out.byte_string(data)
    return out.getvalue()


def read_stream_list(data: bytes, offset: int, chunk: str,
                     count: int) -> list[tuple[bytes, int]]:
    """The ``count`` byte strings of a ``chunk`` payload at absolute byte ``offset``, each
    with the absolute byte offset of its first byte.

    Raises:
        FormatError: naming ``chunk`` and the byte offset, when the payload holds another
            count, is cut off or has bytes after the last string.
    """
    r = ByteReader(data, base_offset=offset, chunk=chunk)
    n = r.varint("stream_count", maximum=MAX_STRINGS)
    if n != count:
        raise r.error(f"{n} streams, expected {count}")
    out = []
    for _ in range(n):
        stream = r.byte_string("stream")
        out.append((stream, r.offset - len(stream)))
    r.expect_end(f"the {chunk} payload")
    return out
