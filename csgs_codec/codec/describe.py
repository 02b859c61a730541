"""Facts about a .csgs file for ``csgs info``: the container's, plus what the scene header says."""

from __future__ import annotations

from csgs_codec.chunks.color_streams import rotation_step_summary
from csgs_codec.chunks.far_points import relative_far_count
from csgs_codec.chunks.scene_header import SceneHeader
from csgs_codec.chunks.sh_colour_transform import OPPONENT, parse_colour_transform
from csgs_codec.chunks.view_record import ViewRecord
from csgs_codec.errors import CsgsError, FormatError
from csgs_codec.format import describe, read_layers
from csgs_codec.format.reader import read_frame
from csgs_codec.format.source import open_source


def describe_bitstream(source, *, verify: bool = True) -> dict:
    """:func:`csgs_codec.format.describe` facts, plus, when the file holds a scene header:
    ``gaussians``, ``sh_degree_stored`` / ``sh_degree_coded``, ``quality``, ``grid_bits``,
    ``tiles`` (spatial tiles: one scene header each; counts are summed over them),
    ``levels`` in a file with levels of detail (per level: ``level``, ``tiles``,
    ``gaussians``, ``bytes`` of its chunk frames; ``gaussians`` is then level 0's),
    ``far_outliers`` (positions coded apart from the grid: ``far_relative`` of them with
    relative precision in OUTQ, ``far_exact`` as float32 in OUTL), ``views`` (the viewing
    distribution view pruning followed, when the file records one) and
    ``bits_per_gaussian`` for the file, each layer and each chunk (bytes * 8 / N),
    ``rotation_steps`` (how the first tile's rotation steps follow decoded attributes:
    ``uniform`` or ``footprint`` (scored steps) with its class count and channel coding, when
    its ROTN chunk is present and readable); and always ``semantic_share_percent``, the
    semantic layer's chunk frames as a percentage of the whole file (header and TOC
    included).

    Reads only the base layer's payloads and the first ROTN payload besides the header and
    TOC.
    """
    facts = describe(source, verify=verify)
    total = facts["file_bytes"]
    facts["semantic_share_percent"] = (100.0 * facts["layers"]["semantic"]["bytes"] / total
                                       if total else 0.0)
    if not any(c["type"] == "SCNE" for c in facts["chunks"]):
        return facts
    container = read_layers(source, layers=set())
    # A tiled file (FORMAT §12.22) has one SCNE per tile: counts add up, degrees and grid
    # bits are the largest.
    headers = [SceneHeader.from_bytes(bytes(container.payloads[e.index]), e.offset + 8)
               for e in container.toc if e.type == "SCNE"]
    header = headers[0]
    n = sum(h.count for h in headers)
    far = sum(h.far_count for h in headers)
    levels = _levels(container, facts["chunks"])
    if levels is not None:
        facts["levels"] = levels
        n = levels[0]["gaussians"]  # the scene: level 0 (coarser levels are extra)
    facts.update(gaussians=n, sh_degree_stored=header.sh_degree_stored,
                 sh_degree_coded=max(h.sh_degree_coded for h in headers),
                 quality=header.quality, grid_bits=max(h.grid_bits for h in headers),
                 far_outliers=far, tiles=len(headers))
    relative = relative_far_count(container)
    facts.update(far_relative=relative, far_exact=far - relative)
    try:
        record = _view_record(container)
    except FormatError as err:  # informative only: the file stays valid (§12.21)
        facts["views"] = {"unreadable": str(err)}
    else:
        if record is not None:
            facts["views"] = {"source": record.source, "count": record.views,
                              "left_out": record.left_out, "description": record.description}
    steps = _rotation_steps(source, container)
    if steps is not None:
        facts["rotation_steps"] = steps
    opponent = _opponent_bands(source, container)
    if opponent is not None:
        facts["sh_opponent_bands"] = opponent
    if n:
        facts["bits_per_gaussian"] = 8 * facts["file_bytes"] / n
        for layer in facts["layers"].values():
            layer["bits_per_gaussian"] = 8 * layer["bytes"] / n
        for chunk in facts["chunks"]:
            chunk["bits_per_gaussian"] = 8 * chunk["bytes"] / n
    return facts


def _levels(container, chunks: list[dict]) -> list[dict] | None:
    """Per level of detail of a file whose tile index has levels: its tiles, Gaussians and
    chunk bytes (frames); None for a file without levels."""
    from csgs_codec.chunks.tile_index import TileIndex

    entry = next((e for e in container.toc if e.type == "TIDX"), None)
    if entry is None:
        return None
    index = TileIndex.from_bytes(bytes(container.payloads[entry.index]), entry.offset + 8)
    if index.levels == 1:
        return None
    level_of = {i: t.level for i, t in enumerate(index.tiles)}
    out = [{"level": k, "tiles": 0, "gaussians": 0, "bytes": 0} for k in range(index.levels)]
    for tile in index.tiles:
        out[tile.level]["tiles"] += 1
        out[tile.level]["gaussians"] += tile.count
    for chunk in chunks:
        if chunk["type"] != "TIDX" and chunk["tile"] in level_of:
            out[level_of[chunk["tile"]]]["bytes"] += chunk["bytes"]
    return out


def _first_frame(source, container, code: str):
    """(TOC entry, payload bytes) of the first chunk of type ``code``, or None when absent.

    Raises:
        CsgsError, OSError: the payload cannot be read (callers treat it as informative).
    """
    entry = next((e for e in container.toc if e.type == code), None)
    if entry is None:
        return None
    src = open_source(source)
    try:
        return entry, read_frame(src, entry)
    finally:
        src.close()


def _opponent_bands(source, container) -> list[int] | None:
    """The SH bands the first SHXF record (FORMAT §12.24) codes in opponent colours, or None
    without a readable record (informative only)."""
    try:
        found = _first_frame(source, container, "SHXF")
        if found is None:
            return None
        entry, data = found
        scene = next(e for e in container.toc if e.type == "SCNE" and e.tile == entry.tile)
        degree = SceneHeader.from_bytes(bytes(container.payloads[scene.index]),
                                        scene.offset + 8).sh_degree_coded
        transforms = parse_colour_transform(data, entry.offset + 8, degree)
    except (CsgsError, OSError, StopIteration):
        return None
    return [band for band, t in enumerate(transforms, start=1) if t == OPPONENT]


def _rotation_steps(source, container) -> dict | None:
    """How the first ROTN chunk's coded channels set their steps ({"mode", "name",
    "classes"}; the encoder gives every coded channel of a stream the same kind), or None
    when the chunk is absent, cut off or unreadable (informative only)."""
    try:
        found = _first_frame(source, container, "ROTN")
        if found is None:
            return None
        entry, data = found
        return rotation_step_summary(data, entry.offset + 8)
    except (CsgsError, OSError):
        return None


def _view_record(container) -> ViewRecord | None:
    """The ``vdis`` record of the base layer, or None."""
    entry = next((e for e in container.toc if e.type == "vdis"), None)
    if entry is None or entry.index not in container.payloads:
        return None
    return ViewRecord.from_bytes(bytes(container.payloads[entry.index]), entry.offset + 8)

