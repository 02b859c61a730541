"""What a scene file was: its format, version and whether reading it undid a lossy coding."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class SceneSource:
    """The facts ``csgs info`` prints about a scene file besides the scene itself.

    Attributes:
        format: short name ("ply", "compressed-ply", "splat", "ksplat", "spz", "sog",
            "glb", "csgs").
        label: the format as people call it ("Niantic SPZ", "PlayCanvas SOG", ...).
        version: the format version the file declares, or None where it has none.
        lossy: True when the file holds quantized attributes (re-encoding them compounds
            the loss); False for full-precision float files.
        details: format-specific facts (compression level, fractional bits, ...).
    """

    format: str
    label: str
    version: str | None = None
    lossy: bool = False
    details: dict = field(default_factory=dict)

    def title(self) -> str:
        """``label`` with its version, e.g. "Niantic SPZ v4"."""
        return f"{self.label} v{self.version}" if self.version else self.label


def warn_if_lossy(source: SceneSource, path) -> None:
    """Warn (:class:`~csgs_codec.errors.CompoundedLossWarning`) when ``source`` is a lossy
    format: re-encoding quantized values compounds the loss."""
    import warnings

    from csgs_codec.errors import CompoundedLossWarning

    if source.lossy:
        warnings.warn(f"{path}: {source.title()} is a lossy format; encoding it quantizes "
                      "values that were already quantized, so the losses add up (encode "
                      "the full-precision original when you have it)", CompoundedLossWarning,
                      stacklevel=3)
