"""The fuzz oracle: decode one input and say whether the decoder behaved.

Behaving means ``Decoder().decode(data, layers="color,semantic")`` (``AnchorDecoder`` when the
TOC lists an anchor-scene chunk, as a caller that dispatches on
:func:`~csgs_codec.codec.anchor_decoder.is_anchor_file` would) either returns a scene whose
float arrays (and MLP weights) are all finite, or raises one of :data:`ALLOWED_ERRORS`; a
file with levels of detail (FORMAT §12.22) is decoded at every level, level 0 first, so
damage in a coarse tile is read too (the first error ends it); and the
Python heap peak (tracemalloc, which sees numpy's buffers) stays within :func:`memory_bound`.
Anything else (any other exception, a non-finite value, an allocation over the bound) is a
crash.
"""

from __future__ import annotations

import time
import tracemalloc
from dataclasses import dataclass

import numpy as np

from csgs_codec.chunks.tile_index import TileIndex
from csgs_codec.codec.decoder import Decoder
from csgs_codec.errors import CsgsError, FormatError, UnsupportedError
from csgs_codec.format.reader import read_frame
from csgs_codec.format.source import open_source
from csgs_codec.format.toc import read_toc

try:  # the anchor-scene decoder, where this checkout has it
    from csgs_codec.codec.anchor_decoder import AnchorDecoder, is_anchor_file
except ImportError:  # pragma: no cover - older checkouts
    AnchorDecoder = is_anchor_file = None

#: Errors a decoder may raise on a damaged file. FormatError is the expected one; a well formed
#: file using something this decoder does not know may give UnsupportedError.
ALLOWED_ERRORS = (FormatError, UnsupportedError)
LAYERS = "color,semantic"
#: Memory bound: this many times the input size, plus a fixed allowance.
MEMORY_FACTOR = 64
MEMORY_ALLOWANCE = 4 << 20
FLOAT_FIELDS = ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations", "semantic",
                "features", "offsets", "scaling")


@dataclass(frozen=True)
class Outcome:
    """What one decode did.

    Attributes:
        kind: "ok", the name of an allowed error class, or "crash".
        detail: for a crash, the exception type and message (or what check failed).
        seconds: wall time of the decode.
        peak_bytes: tracemalloc peak during the decode, above what was allocated before it.
        input_bytes: size of the input.
        stage: for an allowed error, where it was raised (see :func:`error_stage`).
        traced: whether ``peak_bytes`` was measured.
    """

    kind: str
    detail: str
    seconds: float
    peak_bytes: int
    input_bytes: int
    stage: str | None = None
    traced: bool = True

    @property
    def crashed(self) -> bool:
        """True when the decoder misbehaved on this input."""
        return self.kind == "crash"

    @property
    def memory_ratio(self) -> float:
        """Peak heap bytes per input byte."""
        return self.peak_bytes / max(self.input_bytes, 1)


#: Messages of errors raised by the container reader before any chunk decoder runs.
_CONTAINER_MESSAGES = ("frame ", "truncated: the chunk", "TOC entry", "unknown critical chunk",
                       "truncated: the TOC", "toc_size", "not a .csgs file", "major version",
                       "reserved flag", "bytes follow the last chunk", "chunk_count",
                       "truncated: the 16-byte header", "the tile index must be",
                       "is not in the tile index", "chunk TIDX appears")


def error_stage(error: CsgsError) -> str:
    """Where an allowed error came from: "crc", "container" or "payload" (a chunk decoder)."""
    message = error.message
    if "CRC" in message:
        return "crc"
    if error.chunk is None or message.startswith(_CONTAINER_MESSAGES):
        return "container"
    return "payload"


def memory_bound(input_bytes: int) -> int:
    """Largest heap peak (bytes) the decoder may reach on an input of ``input_bytes``."""
    return MEMORY_FACTOR * input_bytes + MEMORY_ALLOWANCE


def _nonfinite_field(scene) -> str | None:
    for name in FLOAT_FIELDS:
        values = getattr(scene, name, None)
        if values is not None and values.size and not np.all(np.isfinite(values)):
            return name
    mlps = getattr(scene, "mlps", None)
    if mlps is not None:
        for head_name, head in mlps.heads().items():
            for name, values in head.arrays().items():
                if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
                    return f"MLP {head_name}.{name}"
    return None


def decode(data: bytes):
    """Decode ``data`` as a caller would: anchor files with AnchorDecoder, others with Decoder."""
    if AnchorDecoder is not None and is_anchor_file(data):
        return AnchorDecoder().decode(data, layers=LAYERS)
    return Decoder().decode(data, layers=LAYERS)


def decode_every_level(data: bytes) -> list:
    """Every level of ``data`` as :func:`decode` would decode it, level 0 first (one scene
    for a file without levels of detail or an anchor scene); raises what a decode raises."""
    if AnchorDecoder is not None and is_anchor_file(data):
        return [AnchorDecoder().decode(data, layers=LAYERS)]
    return decode_levels(data)


def decode_levels(data: bytes) -> list:
    """Every level of detail of the Gaussian scene ``data`` decoded by ``Decoder``, level 0
    first (one scene for a file without levels); raises what a decode raises."""
    scenes = [Decoder().decode(data, LAYERS)]
    return scenes + [Decoder().decode(data, LAYERS, lod=k) for k in range(1, levels_of(data))]


def levels_of(data: bytes) -> int:
    """Levels of detail of ``data``, a file that decodes (1 without a tile index)."""
    src = open_source(data)
    entry = next((e for e in read_toc(src).entries if e.type == "TIDX"), None)
    return 1 if entry is None else TileIndex.from_bytes(read_frame(src, entry)).levels


def run_decoder(data: bytes, trace: bool = True) -> Outcome:
    """Decode ``data`` under the oracle.

    Args:
        trace: measure the heap peak (tracemalloc must already be tracing; it about doubles
            the decode time). Without it ``peak_bytes`` is 0 and memory is not checked.
    """
    if trace:
        tracemalloc.reset_peak()
        before = tracemalloc.get_traced_memory()[0]
    start = time.perf_counter()
    kind, detail, stage = "ok", "", None
    scenes = []
    try:
        scenes = decode_every_level(data)
    except ALLOWED_ERRORS as err:
        kind, stage = type(err).__name__, error_stage(err)
    except CsgsError as err:  # a CsgsError, but not the right one for damaged bytes
        kind, detail = "crash", f"{type(err).__name__}: {err}"
    except Exception as err:  # noqa: BLE001 - any other exception is what we hunt for
        kind, detail = "crash", f"{type(err).__name__}: {err}"
    seconds = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1] - before if trace else 0
    for level, scene in enumerate(scenes):
        bad = _nonfinite_field(scene)
        if bad is not None:
            where = f" of level {level}" if level else ""
            kind, detail = "crash", f"non-finite value in decoded {bad}{where}"
            break
    if trace and kind != "crash" and peak > memory_bound(len(data)):
        kind, detail = "crash", f"heap peak {peak} bytes exceeds {memory_bound(len(data))}"
    return Outcome(kind, detail, seconds, peak, len(data), stage, trace)
