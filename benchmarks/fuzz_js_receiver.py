"""Fuzz the JavaScript receiver against the Python decoder with mutated real files.

    python benchmarks/fuzz_js_receiver.py --inputs 20000 [--seed 0] [--batch 100] [--start I]
        [--seeds campaign|default-encodes] [--only-seeds TEXT] [--out fuzz_js.json]
        [--crash-dir DIR]

Inputs are the reproducible mutant sequence of tests/fuzz/campaign.py over either the decoder
campaign's standard-scene seeds (``campaign``) or the default encodes (``Encoder()``, what
`csgs encode` writes) of the sample and of the repository's SH-3 capture
(``default-encodes``). Each input is decoded by both decoders (tests/fuzz/js_differential.py):
a disagreement is a receiver exception other than FormatError / UnsupportedError, a receiver
process that died or hung, one decoder accepting what the other refuses, different arrays, a
different kind of error, or a rejection naming another chunk or byte offset. The JSON document
(schema csgs-bench/1) is rewritten after every batch. Disagreeing inputs are written to
``--crash-dir`` as ``<index>.csgs`` with a ``.json`` beside each. Exit status 1 when any
input disagreed.

``--only-seeds TEXT`` keeps the seeds whose name contains one of TEXT's comma-separated parts
(e.g. ``level,tiled`` for the files with a tile index), as benchmarks/fuzz_decoder.py does;
``--start I`` begins at input I (a stopped run goes on from where its JSON's ``inputs`` say
it stopped).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_common import REPO, document, emit, save_failing_inputs  # noqa: E402

from tests.fuzz.container_edit import split_chunks  # noqa: E402
from tests.fuzz.js_differential import (  # noqa: E402
    DifferentialSummary,
    run_differential,
    standard_seeds,
)
from tests.fuzz.seeds import Seed, build_seeds  # noqa: E402

DEFAULT_ENCODE_SOURCES = (REPO / "samples" / "donut.ply",
                          REPO / "benchmarks" / "data" / "yashica_t4_top8192.ply")


def default_encode_seeds() -> list[Seed]:
    """Seeds that are what `csgs encode` writes with no flags for the two bundled scenes."""
    from csgs_codec import Encoder
    from csgs_codec.codec.files import read_scene

    seeds = []
    for source in DEFAULT_ENCODE_SOURCES:
        data = Encoder().encode(read_scene(source))
        seeds.append(Seed(f"default:{source.stem}", data, tuple(split_chunks(data)), 1.0))
    return seeds


def _result(summary: DifferentialSummary, args, seeds, elapsed: float) -> dict:
    return {
        "requested_inputs": args.inputs,
        "start": args.start,
        "inputs": summary.inputs,
        "complete": summary.inputs == args.inputs,
        "disagreements": len(summary.disagreements),
        "disagreement_details": [
            {"index": d.index, "seed": d.seed, "operators": list(d.operators), "kind": d.kind,
             "detail": d.detail[:500]} for d in summary.disagreements[:50]],
        "python_outcomes": dict(summary.outcomes),
        "receiver_slowest_ms": [{"index": i, "ms": round(ms, 3)}
                                for ms, i in summary.slowest_ms],
        "receiver_max_rss_bytes": summary.max_rss_bytes,
        "campaign_seed": args.seed,
        "seed_set": args.seeds,
        "only_seeds": args.only_seeds,
        "seeds": [{"name": s.name, "bytes": len(s.data), "weight": s.weight} for s in seeds],
        "batch": args.batch,
        "elapsed_s": round(elapsed, 1),
        "inputs_per_s": round(summary.inputs / max(elapsed, 1e-9), 1),
    }


def _save(summary: DifferentialSummary, crash_dir: Path | None) -> None:
    save_failing_inputs(crash_dir, [
        (str(d.index), d.data, {"index": d.index, "seed": d.seed, "operators": list(d.operators),
                                "kind": d.kind, "detail": d.detail})
        for d in summary.disagreements])


def main() -> int:
    """Run the campaign; exit status 1 when any input disagreed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=0, help="campaign seed")
    parser.add_argument("--batch", type=int, default=100, help="inputs per receiver process")
    parser.add_argument("--start", type=int, default=0, help="first input index")
    parser.add_argument("--seeds", choices=("campaign", "default-encodes"), default="campaign")
    parser.add_argument("--out", help="write the JSON here (rewritten after every batch)")
    parser.add_argument("--crash-dir", type=Path, help="write disagreeing inputs here")
    parser.add_argument("--only-seeds", default=None, metavar="TEXT",
                        help="fuzz only the seeds whose name contains TEXT")
    args = parser.parse_args()

    seeds = (standard_seeds(build_seeds()) if args.seeds == "campaign"
             else default_encode_seeds())
    if args.only_seeds is not None:
        parts = [part for part in args.only_seeds.split(",") if part]
        seeds = [s for s in seeds if any(part in s.name for part in parts)]
        if not seeds:
            parser.error(f"no seed name contains {args.only_seeds!r}")
    total = DifferentialSummary()
    began = time.perf_counter()
    end = args.start + args.inputs
    for start in range(args.start, end, args.batch):
        part = run_differential(seeds, start, min(args.batch, end - start), args.seed,
                                batch=args.batch)
        total.merge(part)
        _save(part, args.crash_dir)
        if args.out:
            emit(document("fuzz_js_receiver", [_result(
                total, args, seeds, time.perf_counter() - began)]), args.out)
    emit(document("fuzz_js_receiver", [_result(total, args, seeds,
                                                time.perf_counter() - began)]), args.out)
    return 1 if total.disagreements else 0


if __name__ == "__main__":
    sys.exit(main())
