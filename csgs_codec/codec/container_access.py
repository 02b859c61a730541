"""What both decoders ask of a read container: the layers to read and one chunk's payload."""

from __future__ import annotations

from csgs_codec.errors import FormatError, InputError


def parse_layers(layers) -> set[str]:
    """Normalise a layers argument ("color", "color,semantic", "semantic,color", or an
    iterable of names) to a set; the color layer is always decoded.

    Raises:
        InputError: an unknown layer name, or no layer at all ("" does not mean color).
    """
    names = set(layers.split(",")) if isinstance(layers, str) else set(layers)
    names = {n.strip() for n in names if n.strip()}
    if not names:
        raise InputError(f"no layer given ({layers!r}); choose 'color' or 'color,semantic'",
                         property="layers")
    unknown = names - {"color", "semantic", "base"}
    if unknown:
        raise InputError(f"unknown layer(s) {sorted(unknown)}; choose from color, semantic",
                         property="layers")
    return (names | {"color"}) - {"base"}


def single_payload(container, code: str) -> tuple[bytes, int]:
    """(payload, absolute offset of the payload) of the one chunk of type ``code``.

    Raises:
        FormatError: the chunk is missing, appears more than once, or was cut off.
    """
    entries = [e for e in container.toc if e.type == code]
    if not entries:
        raise FormatError(f"required chunk {code} is missing", chunk=code)
    if len(entries) > 1:
        raise FormatError(f"chunk {code} appears {len(entries)} times", chunk=code,
                          offset=entries[1].offset)
    entry = entries[0]
    if entry.index not in container.payloads:
        raise FormatError(f"chunk {code} is cut off (stream truncated)", chunk=code,
                          offset=entry.offset)
    return bytes(container.payloads[entry.index]), entry.offset + 8
