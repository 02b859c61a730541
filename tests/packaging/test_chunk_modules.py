"""A chunk's writer and reader live in one module (issue #33): the payloads of the chunk
families in csgs_codec/chunks/ are laid out and parsed there, and nowhere else parses
them (a ByteReader naming one of their chunks outside that package would be a second
reader)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "csgs_codec"
#: chunk type -> the module under csgs_codec/chunks/ that holds its payload.
FAMILIES = {"SHDC": "color_streams", "SHBA": "color_streams", "SHBB": "color_streams",
            "SHBC": "color_streams", "OPAC": "color_streams", "SCAL": "color_streams",
            "ROTN": "color_streams", "OUTL": "far_points", "OUTQ": "far_points",
            "SEMF": "semantic", "SEML": "semantic", "SEMC": "semantic",
            "SCNE": "scene_header", "TIDX": "tile_index", "vdis": "view_record",
            "ANCH": "anchor_payloads", "AMLP": "anchor_payloads"}
#: Families whose payload is a class with ``to_bytes``/``from_bytes`` (or that the anchor
#: codec assembles from streams) rather than module functions.
CLASS_FAMILIES = {"scene_header", "tile_index", "view_record", "anchor_payloads"}


def _readers() -> dict[str, set[str]]:
    """Chunk type -> the modules (relative paths) that build a ByteReader naming it."""
    found: dict[str, set[str]] = {}
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "ByteReader"):
                continue
            for keyword in node.keywords:
                if keyword.arg == "chunk" and isinstance(keyword.value, ast.Constant):
                    found.setdefault(keyword.value.value, set()).add(
                        str(path.relative_to(PACKAGE)))
    return found


def test_the_chunk_families_are_parsed_only_in_their_module():
    readers = _readers()
    for code, module in FAMILIES.items():
        outside = {m for m in readers.get(code, set()) if m != f"chunks/{module}.py"}
        assert not outside, f"{code} is also parsed in {sorted(outside)}"
    # The check sees the readers it guards (a renamed ByteReader would blind it).
    assert {"chunks/semantic.py"} <= readers["SEML"] and "chunks/far_points.py" in readers["OUTL"]


def test_each_chunk_module_writes_and_reads():
    for module in set(FAMILIES.values()) - CLASS_FAMILIES:
        tree = ast.parse((PACKAGE / "chunks" / f"{module}.py").read_text())
        names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
        assert any(n.startswith("read_") for n in names), module
        assert any(n.endswith("_payload") and not n.startswith("read_") for n in names), module
