"""What both decoders ask of a layers argument: the layers to read."""

from __future__ import annotations

from csgs_codec.errors import InputError


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

