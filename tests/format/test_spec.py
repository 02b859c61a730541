"""spec/FORMAT.md agrees with the code: chunk registry, byte tables, limits, worked example."""

from __future__ import annotations

import re

import pytest

from csgs_codec.format import CHUNK_TYPES, MAGIC, container_bytes, layout
from tests.conformance import VECTORS_DIR
from tests.conformance.container import annotated_hex, worked_example_chunks
from tests.conftest import REPO

SPEC = (REPO / "spec" / "FORMAT.md").read_text(encoding="utf-8")
BYTE_TABLE_HEADER = ["Offset", "Size", "Field", "Range", "Invalid if"]


def _cells(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip().strip("|").split("|")]


def _tables(text: str) -> list[tuple[list[str], list[list[str]]]]:
    """Every markdown table as (header cells, rows of cells)."""
    tables, lines = [], text.splitlines()
    i = 0
    while i < len(lines):
        if lines[i].startswith("|") and i + 1 < len(lines) and lines[i + 1].startswith("|---"):
            header, rows = _cells(lines[i]), []
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                rows.append(_cells(lines[i]))
                i += 1
            tables.append((header, rows))
        else:
            i += 1
    return tables


def _byte_table_rows() -> dict[str, list[str]]:
    """Rows of the container's byte tables (§4-§6: header, TOC, chunk frame) by field name."""
    container_part = SPEC[SPEC.index("## 4. Header"):SPEC.index("## 7. Layers")]
    rows: dict[str, list[str]] = {}
    for header, body in _tables(container_part):
        if header == BYTE_TABLE_HEADER:
            for row in body:
                name = row[2].strip("`")
                assert name not in rows, f"field {name} in two container byte tables"
                rows[name] = row
    return rows


def _section(number: int) -> str:
    match = re.search(rf"^## {number}\. .*?(?=^## {number + 1}\. |\Z)", SPEC, re.M | re.S)
    assert match, f"no section {number}"
    return match.group(0)


def test_every_registered_chunk_type_has_a_payload_section():
    payloads = _section(12)
    assert payloads.startswith("## 12. Chunk payloads")
    anchors = _section(17)
    assert anchors.startswith("## 17. Anchor scenes")
    for code in CHUNK_TYPES:
        assert (re.search(rf"^### 12\.\d+ `{code}`", payloads, re.M)
                or re.search(rf"^### 17\.\d+ .*`{code}`", anchors, re.M)), code


def test_spec_registry_table_matches_the_code_registry():
    table = next(rows for header, rows in _tables(SPEC)
                 if header[:3] == ["Type", "Layer", "Critical"])
    spec_rows = {row[0].strip("`"): row for row in table}
    for code, info in CHUNK_TYPES.items():
        row = spec_rows[code]
        assert row[1] == ("any" if info.layer is None else info.layer.label), code
        assert row[2] == ("yes" if info.critical else "no"), code
        assert row[4] == info.description, code


FIELD_TABLES = (layout.HEADER_FIELDS + layout.TOC_FIELDS + layout.TOC_ENTRY_FIELDS
                + layout.TOC_TRAILER_FIELDS + layout.FRAME_FIELDS + layout.FRAME_TRAILER_FIELDS)


@pytest.mark.parametrize("field", FIELD_TABLES, ids=lambda f: f.name)
def test_every_field_the_reader_reads_is_in_a_byte_table(field):
    row = _byte_table_rows().get(field.name)
    assert row is not None, f"field {field.name} is not in any byte table of FORMAT.md"
    assert row[1] == field.size_text
    if field.offset is not None:
        assert row[0] == str(field.offset)


def test_payload_field_is_in_the_frame_table():
    assert _byte_table_rows()["payload"][1] == "`length`"


def test_magic_in_the_spec_is_the_magic_in_the_code():
    row = _byte_table_rows()["magic"]
    assert bytes.fromhex(row[3].strip("`")) == MAGIC


@pytest.mark.parametrize("name", ["MAX_TOC_SIZE", "MAX_CHUNKS", "MAX_TILE",
                                  "MAX_PAYLOAD_SIZE"])
def test_limits_in_the_spec_are_the_limits_in_the_code(name):
    table = next(rows for header, rows in _tables(SPEC) if header[:2] == ["Limit", "Value"])
    values = {row[0].strip("`"): int(row[1]) for row in table}
    assert values[name] == getattr(layout, name)


def _worked_example_block() -> str:
    match = re.search(r"<!-- worked-example:.*?-->\n```text\n(.*?)\n```", SPEC, re.S)
    assert match, "no worked example block"
    return match.group(1)


def test_worked_example_hex_is_what_the_writer_produces():
    data = container_bytes(worked_example_chunks())
    block = _worked_example_block()
    spec_bytes = bytearray()
    for line in block.splitlines():
        offset, hex_part = line.split("|")[0].split(None, 1)
        assert int(offset, 16) == len(spec_bytes), line
        spec_bytes += bytes.fromhex(hex_part)
    assert bytes(spec_bytes) == data


def test_worked_example_annotations_are_generated():
    assert _worked_example_block() == annotated_hex(container_bytes(worked_example_chunks()))


def test_conformance_section_names_every_container_vector():
    section = _section(14)
    for path in sorted((VECTORS_DIR / "container").glob("*.json")):
        assert f"`{path.stem}`" in section, path.stem
