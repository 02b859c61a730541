"""JSON-ready facts about a .csgs container (for ``csgs info FILE.csgs [--json]``).

Reads only the header and the TOC unless asked to verify the chunk CRCs; imports no torch.
"""

from __future__ import annotations

from csgs_codec.errors import FormatError
from csgs_codec.format.chunk_types import CHUNK_TYPES
from csgs_codec.format.layout import Layer
from csgs_codec.format.reader import name_source, read_frame
from csgs_codec.format.source import SourceLike, open_source
from csgs_codec.format.toc import read_toc


def describe(source: SourceLike, verify: bool = False) -> dict:
    """Facts about the container in ``source``, as a JSON-ready dict.

    Keys: ``kind`` ('csgs'), ``file`` (path or None), ``version`` ('major.minor'),
    ``major_version``, ``minor_version``, ``flags``, ``bytes`` (bytes in the source),
    ``file_bytes`` (bytes of the complete file per the TOC), ``complete`` (source holds every
    chunk), ``header_bytes`` (header + TOC + TOC CRC), ``layers`` (name -> ``chunks``, ``bytes``
    (frames), ``payload_bytes``, ``present``), ``chunks`` (one dict per TOC entry: ``index``,
    ``type``, ``layer``, ``tile``, ``offset``, ``bytes`` (frame), ``payload_bytes``,
    ``critical``, ``known``, ``description``, ``present``) and ``verified``.
    ``header_bytes`` plus every layer's ``bytes`` equals ``file_bytes``.

    Args:
        source: bytes, a path, or a seekable binary file.
        verify: also read every chunk present and check its frame and CRC.

    Raises:
        FormatError: the header or TOC is malformed, or (with ``verify``) a chunk is.
        InputError: the source cannot be opened.
    """
    src = open_source(source)
    try:
        toc = read_toc(src)
        if verify:
            for entry in toc.entries:
                if entry.end <= src.size:
                    read_frame(src, entry)
    except FormatError as err:
        name_source(err, src)
        raise
    finally:
        src.close()
    layers = {layer.label: {"chunks": 0, "bytes": 0, "payload_bytes": 0, "present": True}
              for layer in Layer}
    chunks = []
    for entry in toc.entries:
        present = entry.end <= toc.source_size
        known = CHUNK_TYPES.get(entry.type)
        chunks.append({
            "index": entry.index, "type": entry.type, "layer": entry.layer.label,
            "tile": entry.tile, "offset": entry.offset, "bytes": entry.frame_size,
            "payload_bytes": entry.length, "critical": entry.critical,
            "known": known is not None,
            "description": known.description if known is not None else None,
            "present": present,
        })
        totals = layers[entry.layer.label]
        totals["chunks"] += 1
        totals["bytes"] += entry.frame_size
        totals["payload_bytes"] += entry.length
        totals["present"] = totals["present"] and present
    return {
        "kind": "csgs", "file": src.name,
        "version": f"{toc.major_version}.{toc.minor_version}",
        "major_version": toc.major_version, "minor_version": toc.minor_version,
        "flags": toc.flags, "bytes": toc.source_size, "file_bytes": toc.file_size,
        "complete": toc.source_size >= toc.file_size,
        "header_bytes": toc.header_and_toc_size, "layers": layers, "chunks": chunks,
        "verified": verify,
    }


def format_description(facts: dict) -> str:
    """Human-readable text for the facts returned by :func:`describe`."""
    name = facts["file"] or "<bytes>"
    state = "complete" if facts["complete"] else (
        f"cut at byte {facts['bytes']:,} of {facts['file_bytes']:,}")
    per_g = "bits_per_gaussian" in facts
    bits = lambda entry: (f"{entry['bits_per_gaussian']:>9.2f}"  # noqa: E731
                          if per_g else "")
    lines = [f"{name}: csgs {facts['version']}, flags 0x{facts['flags']:04x}, "
             f"{facts['file_bytes']:,} bytes ({state})"]
    if per_g:
        lines.append(f"  scene            {facts['gaussians']:,} Gaussians, SH degree "
                     f"{facts['sh_degree_stored']} ({facts['sh_degree_coded']} coded), "
                     f"quality {facts['quality']}, {facts['bits_per_gaussian']:.2f} "
                     "bits/Gaussian")
    for level in facts.get("levels", ()):
        lines.append(f"  level {level['level']:<2}         {level['gaussians']:,} Gaussians in "
                     f"{level['tiles']} tiles, {level['bytes']:,} bytes")
    if facts.get("far_outliers"):
        relative = facts.get("far_relative", 0)
        lines.append(f"  coded apart      {facts['far_outliers']:,} positions outside the grid "
                     f"({relative:,} relative precision, OUTQ; "
                     f"{facts['far_outliers'] - relative:,} exact, OUTL)")
    views = facts.get("views")
    if views and "unreadable" in views:
        lines.append(f"  views            record unreadable, ignored ({views['unreadable']})")
    elif views:
        lines.append(f"  views            {views['description']} ({views['source']}); "
                     f"{views['left_out']:,} Gaussians left out for them")
    steps = facts.get("rotation_steps")
    if steps:
        lines.append(f"  rotation steps   {steps['name']}"
                     + (f" (scored steps, {steps['classes']} classes)"
                        if steps["classes"] > 1 else " (one step)"))
    opponent = facts.get("sh_opponent_bands")
    if opponent is not None:
        lines.append("  SH colours       " + (
            f"bands {', '.join(map(str, opponent))} in opponent colours" if opponent
            else "every band as R, G, B"))
    lines.append(f"  header + TOC     {facts['header_bytes']:>12,} bytes")
    for label, layer in facts["layers"].items():
        missing = "" if layer["present"] else "  (not all present)"
        share = f" {bits(layer)} bits/G" if per_g else ""
        lines.append(f"  {label:<16} {layer['bytes']:>12,} bytes in {layer['chunks']} chunks"
                     + share + missing)
    if facts["chunks"]:
        lines.append("  chunks:  type layer     tile       offset        bytes  critical"
                     + ("   bits/G" if per_g else ""))
    for chunk in facts["chunks"]:
        line = (f"           {chunk['type']} {chunk['layer']:<9} {chunk['tile']:>4} "
                f"{chunk['offset']:>12,} {chunk['bytes']:>12,}  "
                f"{'yes' if chunk['critical'] else 'no':<8}" + bits(chunk)
                + ("" if chunk["known"] else " (unknown type)"))
        lines.append(line.rstrip())
    return "\n".join(lines)
