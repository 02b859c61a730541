"""Registry of known chunk types: code, layer, critical bit and a one-line description.

A chunk type is four ASCII letters. Like PNG, the case of the first letter carries the
critical bit: upper case = critical (a decoder that does not know it must reject the layer),
lower case = optional (a decoder that does not know it skips it). To add a chunk type, append
one :class:`ChunkType` row to :data:`_TABLE` and a sub-section under "Chunk payloads" in
spec/FORMAT.md (a test checks every code here appears there).
"""

from __future__ import annotations

from dataclasses import dataclass

from csgs_codec.errors import FormatError
from csgs_codec.format.layout import Layer


@dataclass(frozen=True)
class ChunkType:
    """One registered chunk type.

    Attributes:
        code: four ASCII letters, e.g. ``"fill"``.
        layer: the layer the chunk must be in, or None when any layer may hold it.
        description: one line saying what the payload holds.
    """

    code: str
    layer: Layer | None
    description: str

    @property
    def critical(self) -> bool:
        """True when a decoder must understand the chunk to decode its layer."""
        return is_critical(self.code)


def is_valid_type_code(code: bytes) -> bool:
    """True when ``code`` is four bytes, each an ASCII letter A-Z or a-z."""
    # bytes.isalpha() is true only for the ASCII letters A-Z and a-z.
    return len(code) == 4 and code.isalpha()


def is_critical(code: str) -> bool:
    """True when the first letter of ``code`` is upper case (bit 5 of byte 0 clear)."""
    return not ord(code[0]) & 0x20


def check_type_code(code: str) -> bytes:
    """``code`` as 4 ASCII bytes, or FormatError when it is not four ASCII letters."""
    raw = code.encode("ascii", "replace") if isinstance(code, str) else b""
    if not is_valid_type_code(raw):
        raise FormatError(f"chunk type {code!r} is not four ASCII letters")
    return raw


_TABLE = (
    ChunkType("fill", None,
              "Padding or test bytes; any layer, any content; decoders ignore the payload."),
    ChunkType("TIDX", Layer.BASE,
              "Tile index: each spatial tile's Gaussian count and bounding box."),
    ChunkType("SCNE", Layer.BASE,
              "Scene header: Gaussian count, SH degrees, position grid, far-point count."),
    ChunkType("GEOM", Layer.BASE, "Quantized positions: the octree geometry stream."),
    ChunkType("OUTL", Layer.BASE, "Far outliers: exact float32 positions outside the grid."),
    ChunkType("OUTQ", Layer.BASE,
              "Far points with relative precision: an exponent and 3 mantissas each."),
    ChunkType("vdis", Layer.BASE,
              "View distribution: where the encoder's views came from, how many Gaussians "
              "view pruning left out (informative)."),
    ChunkType("CHYP", Layer.COLOR,
              "Color hyperprior: channel mask and integer network on the Gaussians' cells."),
    ChunkType("SHDC", Layer.COLOR, "SH degree-0 color coefficients (float stream, 3 ch)."),
    ChunkType("SHBA", Layer.COLOR, "SH band 1 coefficients (float stream, 9 ch)."),
    ChunkType("SHBB", Layer.COLOR, "SH band 2 coefficients (float stream, 15 ch)."),
    ChunkType("SHBC", Layer.COLOR, "SH band 3 coefficients (float stream, 21 ch)."),
    ChunkType("SHXF", Layer.COLOR,
              "SH colour transform: which bands are coded in opponent colours."),
    ChunkType("OPAC", Layer.COLOR, "Opacity logits (float stream, 1 ch)."),
    ChunkType("SCAL", Layer.COLOR, "Natural-log scales (float stream, 3 ch)."),
    ChunkType("ROTN", Layer.COLOR,
              "Rotations: dropped-component categorical stream, smallest three (3 ch)."),
    ChunkType("SEMF", Layer.SEMANTIC, "Semantic features: channel names and a float stream."),
    ChunkType("SEML", Layer.SEMANTIC, "Integer labels: a lossless residual stream."),
    ChunkType("SEMC", Layer.SEMANTIC,
              "Semantic codebook: channel names, K prototypes and an instance id per Gaussian."),
    ChunkType("SEMR", Layer.SEMANTIC,
              "Integer labels as runs: distinct labels and run-coded indices, or a label per "
              "SEMC instance."),
    ChunkType("ANCH", Layer.BASE,
              "Anchor scene header: anchor count, F, K, voxel grid, CARM groups, flags."),
    ChunkType("AHYP", Layer.BASE, "Anchor hyperprior: integer network on the anchor cells."),
    ChunkType("ACRM", Layer.BASE, "CARM: integer networks over the decoded feature groups."),
    ChunkType("AMSK", Layer.BASE, "Offset masks: context-coded kept/masked bits."),
    ChunkType("AMLP", Layer.BASE,
              "Scaffold-GS MLP weights (float streams; float16 in version 1)."),
    ChunkType("vorg", Layer.BASE,
              "View origins: up to 32 points an anchor scene was trained to be seen from "
              "(for bakes into standard scenes)."),
    ChunkType("AFEA", Layer.COLOR, "Anchor features f: one residual stream per CARM group."),
    ChunkType("AOFF", Layer.COLOR, "Kept anchor offsets: a residual stream."),
    ChunkType("ASCL", Layer.COLOR, "Anchor scaling (6 per anchor): a residual stream."),
    ChunkType("SHYP", Layer.SEMANTIC, "Semantic hyperprior: integer network on the cells."),
    ChunkType("ASEM", Layer.SEMANTIC,
              "Anchor semantic features: channel names and a residual stream."),
)

#: Known chunk types by code.
CHUNK_TYPES: dict[str, ChunkType] = {row.code: row for row in _TABLE}
