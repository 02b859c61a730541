"""The Python side of the anchor-scene comparisons with the JavaScript receiver: the
reference decoder's result in the receiver CLI's terms, and the comparison of the two."""

from __future__ import annotations

from benchmarks._js_receiver import anchor_hashes
from csgs_codec.codec.anchor_decoder import AnchorDecoder
from csgs_codec.errors import FormatError


def python_anchor_result(data: bytes, layers: str) -> dict:
    """AnchorDecoder's result on ``data`` in the receiver CLI's terms."""
    try:
        scene = AnchorDecoder().decode(data, layers=layers)
    except FormatError as err:
        return {"ok": False, "chunk": err.chunk, "offset": err.offset}
    return {"ok": True, "count": len(scene), "arrays": anchor_hashes(scene),
            "semantic_names": list(scene.semantic_names)}


def assert_same_anchors(js: dict, py: dict, what: str) -> None:
    """The receiver's result equals Python's: the same arrays, or the same refusal place."""
    if py["ok"]:
        assert js["ok"], f"{what}: JavaScript rejected a file Python decodes: {js}"
        assert js["kind"] == "anchors" and js["count"] == py["count"], what
        assert js["arrays"] == py["arrays"], f"{what}: decoded arrays differ"
        assert js["semantic_names"] == py["semantic_names"], what
    else:
        assert not js["ok"] and js["error"] == "FormatError", f"{what}: {js} ({py})"
        assert (js["chunk"], js["offset"]) == (py["chunk"], py["offset"]), \
            f"{what}: JavaScript names {js}, Python {py}"
