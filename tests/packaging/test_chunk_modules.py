"""A chunk's writer and reader live in one module (issue #33): the payloads of the chunk
families in csgs_codec/chunks/ are laid out and parsed there, and nowhere else parses
them (a ByteReader naming one of their chunks outside that package would be a second
reader, and so would a parsing helper handed one of their chunks' names or bytes)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "csgs_codec"
#: chunk type -> the module under csgs_codec/chunks/ that holds its payload.
FAMILIES = {"SHDC": "color_streams", "SHBA": "color_streams", "SHBB": "color_streams",
            "SHBC": "color_streams", "OPAC": "color_streams", "SCAL": "color_streams",
            "ROTN": "color_streams", "OUTL": "far_points", "OUTQ": "far_points",
            "SEMF": "semantic", "SEML": "semantic", "SEMC": "semantic", "SEMR": "semantic",
            "SCNE": "scene_header", "TIDX": "tile_index", "vdis": "view_record",
            "ANCH": "anchor_payloads", "AMLP": "anchor_payloads",
            "AHYP": "anchor_networks", "ACRM": "anchor_networks",
            "AMSK": "anchor_streams", "AFEA": "anchor_streams", "AOFF": "anchor_streams",
            "ASCL": "anchor_streams", "SHYP": "anchor_semantic", "ASEM": "anchor_semantic",
            "CHYP": "color_prior", "SHXF": "sh_colour_transform"}
#: Families whose payload is a class with ``to_bytes``/``from_bytes`` (or that the anchor
#: codec assembles from streams) rather than module functions: the codec may take their
#: payload out of the container and hand it to the class.
CLASS_FAMILIES = {"scene_header", "tile_index", "view_record", "anchor_payloads"}
#: The anchor chunks, read through helpers (entropy decoders, integer networks) as much as
#: through ByteReader: the check must see each of them in its module.
ANCHOR_CHUNKS = ("ANCH", "AMLP", "AHYP", "ACRM", "AMSK", "AFEA", "AOFF", "ASCL", "SHYP",
                 "ASEM")


def _constant(node: ast.AST) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _callee(node: ast.Call) -> str | None:
    """The called name: ``f`` of ``f(...)`` or of ``x.f(...)``."""
    return getattr(node.func, "id", None) or getattr(node.func, "attr", None)


def parsed_chunks(tree: ast.AST) -> set[str]:
    """The chunk types a module's syntax tree parses:

    - a ``ByteReader(..., chunk="XXXX")``;
    - any other call handed ``chunk="XXXX"``, a parsing helper given the chunk's bytes
      (``decode_block``, ``decode_masks``, ``intnet_from_bytes``, ``from_bytes``, ...),
      except raising an error that names the chunk (a callee named ``...Error``);
    - ``container.single_payload("XXXX")`` for a chunk of a family that is not a class
      (their ``read_*`` functions take the container; the codec hands a class family's
      payload to its class).
    """
    found = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        name = _callee(node) or ""
        for keyword in node.keywords:
            code = _constant(keyword.value)
            if keyword.arg == "chunk" and code and not name.endswith("Error"):
                found.add(code)
        if name == "single_payload" and node.args:
            code = _constant(node.args[0])
            if code and FAMILIES.get(code) not in CLASS_FAMILIES:
                found.add(code)
    return found


def _readers() -> dict[str, set[str]]:
    """Chunk type -> the modules (relative paths) that parse it (:func:`parsed_chunks`)."""
    found: dict[str, set[str]] = {}
    for path in PACKAGE.rglob("*.py"):
        for code in parsed_chunks(ast.parse(path.read_text())):
            found.setdefault(code, set()).add(str(path.relative_to(PACKAGE)))
    return found


def test_the_chunk_families_are_parsed_only_in_their_module():
    readers = _readers()
    for code, module in FAMILIES.items():
        outside = {m for m in readers.get(code, set()) if m != f"chunks/{module}.py"}
        assert not outside, f"{code} is also parsed in {sorted(outside)}"
    # The check sees the readers it guards (a renamed ByteReader would blind it).
    assert {"chunks/semantic.py"} <= readers["SEML"] and "chunks/far_points.py" in readers["OUTL"]
    for code in ANCHOR_CHUNKS:
        assert f"chunks/{FAMILIES[code]}.py" in readers.get(code, set()), code


def test_the_check_sees_a_parser_outside_its_module():
    """What the anchor decoder did before its chunks moved counts as parsing them."""
    before = ast.parse(
        'data, offset = container.single_payload("AFEA")\n'
        'kept = decode_block(data, params, chunk="AOFF", base_offset=offset)\n'
        'mask = decode_masks(data, m, k, chunk="AMSK", base_offset=offset)\n'
        'net = IntDenseMLP.from_bytes(data, chunk="ACRM", base_offset=offset)\n'
        'r = ByteReader(data, base_offset=offset, chunk="ASEM")\n'
        'header = AnchorHeader.from_bytes(*container.single_payload("ANCH"))\n'
        'raise FormatError("overflow", chunk="ASCL")\n')
    assert parsed_chunks(before) == {"AFEA", "AOFF", "AMSK", "ACRM", "ASEM"}


def test_each_chunk_module_writes_and_reads():
    for module in set(FAMILIES.values()) - CLASS_FAMILIES:
        tree = ast.parse((PACKAGE / "chunks" / f"{module}.py").read_text())
        names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
        assert any(n.startswith("read_") for n in names), module
        assert any(n.endswith("_payload") and not n.startswith("read_") for n in names), module
