"""Differential fuzzing of the JavaScript receiver against the Python decoder.

Every mutant of a campaign (tests/fuzz/campaign.py's reproducible sequence) is decoded by both
(both layers). They must agree: both decode it, to the same arrays (SHA-256 of each), or both
reject it with the same kind of error (FormatError, or UnsupportedError) naming the same chunk
and byte offset; the receiver must never throw anything else, die or hang. FORMAT §11 makes
error reports informative, but both decoders follow its conventions and §8's order (frames in
TOC order, fields in payload order), so a file with several faults is refused for the same one.

A file with levels of detail (FORMAT §12.22) is decoded by both at every level, level 0 first
(tests/fuzz/oracle.py's decode_levels; the arrays of level k > 0 named "lod<k>/<name>"),
so damage in a coarse tile is compared too.

A file whose TOC lists an ANCH chunk (an anchor scene, FORMAT §17) is decoded by the
reference AnchorDecoder and the receiver's decodeAnchorScene, any other by the Decoder and
decodeScene; outcomes count by kind ("ok" or "anchors-ok" for decoded files).
"""

from __future__ import annotations

import heapq
import json
import subprocess
import tempfile
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from benchmarks._js_receiver import anchor_hashes, node_executable, scene_hashes
from csgs_codec.codec.anchor_decoder import AnchorDecoder, is_anchor_file
from csgs_codec.errors import CsgsError, FormatError, UnsupportedError
from tests.fuzz.campaign import mutant_at
from tests.fuzz.oracle import decode_levels
from tests.fuzz.seeds import Seed

ORACLE = Path(__file__).with_name("js_oracle.mjs")
LAYERS = "color,semantic"
#: A batch of k inputs may take this many seconds plus this many per input before it counts
#: as hung (the largest seed, the sample's 360 KB default encode, decodes in about 0.5 s).
BATCH_SECONDS, INPUT_SECONDS = 60.0, 5.0
SLOWEST_KEPT = 10


@dataclass(frozen=True)
class Disagreement:
    """One input on which the receiver misbehaved or disagreed with the Python decoder.

    Attributes:
        kind: "crash" (an exception other than FormatError / UnsupportedError), "died" (the
            process ended or hung on this input alone), "accept" (one decoded it, the other
            refused it), "arrays" (both decoded it, to different arrays), "error-kind" or
            "place" (both refused it, naming different chunks or byte offsets).
    """

    index: int
    seed: str
    operators: tuple[str, ...]
    kind: str
    detail: str
    data: bytes


@dataclass
class DifferentialSummary:
    """Totals of a differential campaign (parts add up with :meth:`merge`).

    Attributes:
        inputs: inputs decoded by both.
        outcomes: count per Python outcome ("ok", "FormatError", "UnsupportedError").
        slowest_ms: the :data:`SLOWEST_KEPT` slowest receiver decodes as (ms, index).
        max_rss_bytes: largest peak resident memory of a receiver process.
        disagreements: the inputs that failed the comparison.
    """

    inputs: int = 0
    outcomes: Counter = field(default_factory=Counter)
    slowest_ms: list[tuple[float, int]] = field(default_factory=list)
    max_rss_bytes: int = 0
    disagreements: list[Disagreement] = field(default_factory=list)

    def merge(self, other: DifferentialSummary) -> None:
        """Add ``other``'s totals to these."""
        self.inputs += other.inputs
        self.outcomes.update(other.outcomes)
        self.slowest_ms = heapq.nlargest(SLOWEST_KEPT, self.slowest_ms + other.slowest_ms)
        self.max_rss_bytes = max(self.max_rss_bytes, other.max_rss_bytes)
        self.disagreements.extend(other.disagreements)


def lists_anchor_chunk(data: bytes) -> bool:
    """Whether the TOC of ``data`` lists an ANCH chunk (False when it cannot be read)."""
    try:
        return is_anchor_file(data)
    except CsgsError:
        return False


def standard_seeds(seeds: Sequence[Seed]) -> list[Seed]:
    """The seeds that are standard (Gaussian) scenes."""
    return [seed for seed in seeds if not lists_anchor_chunk(seed.data)]


def anchor_seeds(seeds: Sequence[Seed]) -> list[Seed]:
    """The seeds that are anchor scenes (their TOC lists ANCH)."""
    return [seed for seed in seeds if lists_anchor_chunk(seed.data)]


def python_outcome(data: bytes) -> dict:
    """The Python decoder's result on ``data`` in the receiver oracle's terms (AnchorDecoder
    for a file whose TOC lists ANCH, else Decoder)."""
    anchors = lists_anchor_chunk(data)
    try:
        if anchors:
            scene = AnchorDecoder().decode(data, layers=LAYERS)
            hashes = anchor_hashes(scene)
        else:
            scene, *coarse = decode_levels(data)
            hashes = scene_hashes(scene)
            for level, other in enumerate(coarse, 1):
                hashes.update({f"lod{level}/{name}": value
                               for name, value in scene_hashes(other).items()})
    except (FormatError, UnsupportedError) as err:
        return {"ok": False, "error": type(err).__name__, "chunk": err.chunk,
                "offset": err.offset, "message": str(err)}
    return {"ok": True, "kind": "anchors" if anchors else "gaussians", "count": len(scene),
            "arrays": hashes, "semantic_names": list(scene.semantic_names)}


def _run_oracle(paths: list[Path]) -> tuple[list[dict], int] | None:
    """(one result per path, peak RSS) from one receiver process, or None when the process
    hung, died or printed fewer results than paths."""
    try:
        done = subprocess.run([node_executable(), str(ORACLE), *map(str, paths)],
                              capture_output=True, text=True, check=False,
                              timeout=BATCH_SECONDS + INPUT_SECONDS * len(paths))
    except subprocess.TimeoutExpired:
        return None
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
    if done.returncode != 0 or len(lines) != len(paths) + 1:
        return None
    return lines[:-1], int(lines[-1]["max_rss_bytes"])


def receiver_outcomes(paths: list[Path]) -> tuple[list[dict], int]:
    """The receiver's result for every path (see tests/fuzz/js_oracle.mjs) and its peak RSS.
    A batch whose process hung or died is split until the input that did it stands alone;
    that input gets ``{"ok": False, "error": "died"}``."""
    run = _run_oracle(paths)
    if run is not None:
        return run
    if len(paths) == 1:
        return [{"ok": False, "error": "died", "message": "the receiver process hung or died",
                 "ms": 0.0}], 0
    half = len(paths) // 2
    first, rss_a = receiver_outcomes(paths[:half])
    second, rss_b = receiver_outcomes(paths[half:])
    return first + second, max(rss_a, rss_b)


def compare(python: dict, receiver: dict) -> tuple[str, str] | None:
    """None when the two results agree, else (disagreement kind, detail)."""
    if not receiver["ok"] and receiver["error"] in ("crash", "died"):
        return receiver["error"], f"{receiver.get('type', 'exit')}: {receiver['message']}"
    if python["ok"] != receiver["ok"]:
        said = {k: receiver.get(k) for k in ("error", "chunk", "offset", "message")}
        return "accept", f"Python {'decodes' if python['ok'] else 'refuses'} it " \
                         f"({python.get('message', '')}); the receiver {said}"
    if python["ok"]:
        if (python.get("kind"), python["count"], python["arrays"],
                python["semantic_names"]) != (receiver.get("kind"), receiver["count"],
                                               receiver["arrays"], receiver["semantic_names"]):
            differ = sorted(k for k in set(python["arrays"]) | set(receiver["arrays"])
                            if python["arrays"].get(k) != receiver["arrays"].get(k))
            return "arrays", f"decoded arrays differ: {differ}"
        return None
    if python["error"] != receiver["error"]:
        return "error-kind", f"Python {python['error']} ({python['message']}), the receiver " \
                             f"{receiver['error']} ({receiver['message']})"
    if (python["chunk"], python["offset"]) != (receiver["chunk"], receiver["offset"]):
        return "place", f"Python: {python['message']}; the receiver: {receiver['message']}"
    return None


def run_differential(seeds: Sequence[Seed], start: int, count: int, campaign_seed: int = 0,
                     batch: int = 100) -> DifferentialSummary:
    """Decode inputs ``start .. start + count - 1`` of the campaign with both decoders and
    total the comparison; the receiver runs on batches of ``batch`` files in one process."""
    summary = DifferentialSummary()
    with tempfile.TemporaryDirectory(prefix="csgs-js-fuzz-") as folder:
        for first in range(start, start + count, batch):
            indices = range(first, min(first + batch, start + count))
            mutants = {i: mutant_at(seeds, i, campaign_seed) for i in indices}
            paths = []
            for i, mutant in mutants.items():
                paths.append(Path(folder) / f"{i}.csgs")
                paths[-1].write_bytes(mutant.data)
            results, rss = receiver_outcomes(paths)
            summary.max_rss_bytes = max(summary.max_rss_bytes, rss)
            for (i, mutant), receiver in zip(mutants.items(), results):
                _count(summary, i, mutant, python_outcome(mutant.data), receiver)
            for path in paths:
                path.unlink()
    return summary


def _count(summary: DifferentialSummary, index: int, mutant, python: dict,
           receiver: dict) -> None:
    """Count one input."""
    summary.inputs += 1
    summary.slowest_ms = heapq.nlargest(SLOWEST_KEPT,
                                        summary.slowest_ms + [(receiver["ms"], index)])
    if python["ok"]:
        summary.outcomes["anchors-ok" if python["kind"] == "anchors" else "ok"] += 1
    else:
        summary.outcomes[python["error"]] += 1
    differ = compare(python, receiver)
    if differ is None:
        return
    summary.disagreements.append(Disagreement(index, mutant.seed, mutant.operators, *differ,
                                              mutant.data))
