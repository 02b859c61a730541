"""Seed files for the interchange-reader fuzzers: the real fixtures in tests/data/formats
(every format csgs reads) plus two ASCII PLYs made from them.

A seed is a file (its bytes) or a SOG folder (its members); ``format`` groups the seeds for
the figures ("ply", "ply-ascii", "compressed-ply", "spz", "sog", "glb", "splat", "ksplat").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from csgs_codec.interchange.ply_header import parse_header

DATA = Path(__file__).resolve().parents[1] / "data" / "formats"
FORMATS = ("ply", "ply-ascii", "compressed-ply", "spz", "sog", "glb", "splat", "ksplat")
#: Rows of donut_sh0.ply kept in the ASCII seeds (small: ASCII parsing is per token).
ASCII_ROWS = 24


@dataclass(frozen=True)
class ReaderSeed:
    """One seed: its name, format group, file suffix and bytes, or for a SOG folder the
    members (name -> bytes) with ``data`` empty."""

    name: str
    format: str
    suffix: str
    data: bytes = b""
    members: dict[str, bytes] = field(default_factory=dict)

    @property
    def size(self) -> int:
        """Bytes of the seed (all members of a folder)."""
        return len(self.data) + sum(len(m) for m in self.members.values())


def _file(name: str, fmt: str, file: str) -> ReaderSeed:
    path = DATA / file
    suffix = ".ply" if file.endswith(".ply") else path.suffix
    return ReaderSeed(name, fmt, suffix, path.read_bytes())


def _folder(name: str, folder: str) -> ReaderSeed:
    members = {p.name: p.read_bytes() for p in sorted((DATA / folder).iterdir())}
    return ReaderSeed(name, "sog", "", members=members)


def ascii_ply_seeds() -> list[ReaderSeed]:
    """Two ASCII PLYs: the first rows of donut_sh0.ply, and the same with integer
    properties (uchar, short, int label) and a face element with a list property."""
    data = (DATA / "donut_sh0.ply").read_bytes()
    header = parse_header(data)
    vertex = header.element("vertex")
    rows = np.frombuffer(data, vertex.dtype("<"), count=ASCII_ROWS, offset=header.header_bytes)
    names = [p.name for p in vertex.properties]
    body = "".join(" ".join(f"{float(row[n]):.9g}" for n in names) + "\n" for row in rows)
    head = ["ply", "format ascii 1.0", f"element vertex {ASCII_ROWS}"]
    head += [f"property float {n}" for n in names] + ["end_header"]
    plain = ("\n".join(head) + "\n" + body).encode()

    typed_head = ["ply", "format ascii 1.0", "comment typed seed",
                  f"element vertex {ASCII_ROWS}"]
    typed_head += [f"property float {n}" for n in names]
    typed_head += ["property uchar red", "property short weight", "property int label",
                   "element face 3", "property list uchar int vertex_indices", "end_header"]
    lines = [line + f" {i * 7 % 256} {i * 911 - 9000} {i % 5}" for i, line in
             enumerate(body.splitlines())]
    lines += ["3 0 1 2", "3 2 3 4", "4 4 5 6 7"]
    typed = ("\n".join(typed_head + lines) + "\n").encode()
    return [ReaderSeed("ply-ascii-donut", "ply-ascii", ".ply", plain),
            ReaderSeed("ply-ascii-typed", "ply-ascii", ".ply", typed)]


def reader_seeds() -> list[ReaderSeed]:
    """Every seed, grouped by format in :data:`FORMATS` order."""
    return [
        _file("ply-donut", "ply", "donut_sh0.ply"),
        _file("ply-brush", "ply", "brush_sh3.ply"),
        *ascii_ply_seeds(),
        _file("compressed-ply-donut", "compressed-ply", "donut_sh0.compressed.ply"),
        _file("compressed-ply-brush", "compressed-ply", "brush_sh3.compressed.ply"),
        _file("spz-v2", "spz", "brush_sh3.v2.spz"),
        _file("spz-v3", "spz", "brush_sh3.v3.spz"),
        _file("spz-v4-brush", "spz", "brush_sh3.v4.spz"),
        _file("spz-v4-donut", "spz", "donut_sh0.v4.spz"),
        _file("sog-zip", "sog", "brush_sh3.sog"),
        _folder("sog-folder-v2", "donut_sh0_sog"),
        _folder("sog-folder-v1", "brush_sh1_sog_v1"),
        _file("glb", "glb", "brush_sh3.glb"),
        _file("splat-donut", "splat", "donut_sh0.splat"),
        _file("splat-brush", "splat", "brush_sh3.splat"),
        _file("ksplat-l0", "ksplat", "brush_sh3.l0.ksplat"),
        _file("ksplat-l1", "ksplat", "brush_sh3.l1.ksplat"),
        _file("ksplat-l2", "ksplat", "brush_sh3.l2.ksplat"),
        _file("ksplat-l2-sh1", "ksplat", "brush_sh3.l2_sh1.ksplat"),
        _file("ksplat-donut-l1", "ksplat", "donut_sh0.l1.ksplat"),
    ]
