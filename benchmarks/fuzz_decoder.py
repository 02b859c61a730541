"""Fuzz the .csgs decoder with mutated real files and report crashes, time and memory.

    python benchmarks/fuzz_decoder.py --inputs 1000000 [--workers 2] [--seed 0]
        [--out fuzz.json] [--crash-dir DIR] [--batch 500] [--trace-every K] [--start I]
        [--max-seconds S] [--only-seeds TEXT]

Inputs are the reproducible mutant sequence of tests/fuzz/campaign.py (input i can be rebuilt
alone with ``tests.fuzz.campaign.mutant_at``), split into batches over worker processes. The
JSON document (schema csgs-bench/1) is rewritten after every batch, so a run stopped early
still leaves its figures; ``complete`` says whether every requested input was decoded (it is
false after ``--max-seconds`` ran out).
``max_seconds_per_input`` is the slowest decode as measured in the run (memory-traced inputs
run about twice as slow, and other processes add noise); ``max_seconds_alone`` times the ten
slowest again, untraced, best of three, after the run. Misbehaving inputs are written to
``--crash-dir`` as ``crash_<index>.csgs`` with a ``.json`` beside each. A batch that finishes
more than ``2 x --batch`` seconds plus a minute after the one before it is reported as a hang
and ends the run (its inputs ran far past the 1 s limit).
``--only-seeds TEXT`` keeps the seeds whose name contains TEXT, or one of TEXT's
comma-separated parts (e.g. ``tiled`` for the multi-tile files); the mutant sequence then
follows that list, which the JSON records.
"""

from __future__ import annotations

import argparse
import multiprocessing
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_common import document, emit, save_failing_inputs  # noqa: E402

from tests.fuzz.campaign import Summary, run_campaign, time_alone  # noqa: E402
from tests.fuzz.oracle import MEMORY_ALLOWANCE, MEMORY_FACTOR  # noqa: E402
from tests.fuzz.seeds import build_seeds  # noqa: E402

_SEEDS = None
_CAMPAIGN_SEED = 0
_TRACE_EVERY = 1


def _init_worker(seeds, campaign_seed: int, trace_every: int) -> None:
    global _SEEDS, _CAMPAIGN_SEED, _TRACE_EVERY
    _SEEDS, _CAMPAIGN_SEED, _TRACE_EVERY = seeds, campaign_seed, trace_every


def _run_batch(bounds: tuple[int, int]) -> tuple[Summary, int]:
    start, count = bounds
    summary = run_campaign(_SEEDS, start, count, _CAMPAIGN_SEED, _TRACE_EVERY)
    return summary, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _save_crashes(summary: Summary, crash_dir: Path | None) -> None:
    save_failing_inputs(crash_dir, [
        (f"crash_{c.index}", c.data, {"index": c.index, "seed": c.seed,
                                      "operators": list(c.operators), "detail": c.detail})
        for c in summary.crashes])


def _result(summary: Summary, args, seeds, elapsed: float, hang: str | None,
            max_rss: int, retimed: float | None = None) -> dict:
    return {
        "requested_inputs": args.inputs,
        "max_seconds_budget": args.max_seconds,
        "inputs": summary.inputs,
        "memory_traced_inputs": summary.traced,
        "complete": summary.inputs == args.inputs and hang is None,
        "crashes": len(summary.crashes),
        "crash_details": sorted({c.detail for c in summary.crashes})[:50],
        "hang": hang,
        "max_seconds_per_input": round(summary.max_seconds, 6),
        "slowest_inputs": [{"index": i, "seconds": round(t, 6)} for t, i in summary.slowest],
        "max_seconds_alone": retimed,
        "max_memory_ratio": round(summary.max_memory_ratio, 3),
        "max_memory_index": summary.max_memory_index,
        "max_peak_bytes": summary.max_peak_bytes,
        "max_share_of_memory_bound": round(summary.max_bound_use, 4),
        "memory_bound": f"{MEMORY_FACTOR} x input bytes + {MEMORY_ALLOWANCE} bytes",
        "worker_max_rss_bytes": max_rss,
        "outcomes": dict(summary.outcomes),
        "error_stages": dict(summary.stages),
        "operators": dict(summary.operators.most_common()),
        "campaign_seed": args.seed,
        "workers": args.workers,
        "seeds": [{"name": s.name, "bytes": len(s.data), "weight": s.weight} for s in seeds],
        "elapsed_s": round(elapsed, 1),
        "inputs_per_s": round(summary.inputs / max(elapsed, 1e-9), 1),
    }


def main() -> int:
    """Run the campaign; exit status 1 when any input crashed or hung."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", type=int, default=10_000)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0, help="campaign seed")
    parser.add_argument("--batch", type=int, default=500, help="inputs per batch")
    parser.add_argument("--start", type=int, default=0, help="first input index")
    parser.add_argument("--out", help="write the JSON here (rewritten after every batch)")
    parser.add_argument("--crash-dir", type=Path, help="write crashing inputs here")
    parser.add_argument("--max-seconds", type=float, default=None,
                        help="stop after this much wall time and report what ran "
                             "(complete is then false)")
    parser.add_argument("--trace-every", type=int, default=1,
                        help="measure the heap peak of every k-th input (1: all; tracing "
                             "about doubles the decode time)")
    parser.add_argument("--only-seeds", default=None, metavar="TEXT",
                        help="fuzz only the seeds whose name contains TEXT")
    args = parser.parse_args()

    seeds = build_seeds()
    if args.only_seeds is not None:
        parts = [part for part in args.only_seeds.split(",") if part]
        seeds = [s for s in seeds if any(part in s.name for part in parts)]
        if not seeds:
            parser.error(f"no seed name contains {args.only_seeds!r}")
    batches = [(s, min(args.batch, args.start + args.inputs - s))
               for s in range(args.start, args.start + args.inputs, args.batch)]
    total, hang, max_rss = Summary(), None, 0
    began = time.perf_counter()
    deadline = began + args.max_seconds if args.max_seconds else float("inf")
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(args.workers, _init_worker, (seeds, args.seed, args.trace_every)) as pool:
        pending = [(b, pool.apply_async(_run_batch, (b,))) for b in batches]
        for bounds, job in pending:
            left = deadline - time.perf_counter()
            try:
                part, rss = job.get(timeout=max(min(2 * args.batch + 60, left), 0.001))
            except multiprocessing.TimeoutError:
                if time.perf_counter() < deadline:
                    hang = (f"batch of inputs {bounds[0]}..{bounds[0] + bounds[1] - 1} did "
                            "not finish")
                pool.terminate()
                break
            total.merge(part)
            max_rss = max(max_rss, rss)
            _save_crashes(part, args.crash_dir)
            if args.out:
                emit(document("fuzz_decoder", [_result(
                    total, args, seeds, time.perf_counter() - began, hang, max_rss)]), args.out)
    elapsed = time.perf_counter() - began
    retimed = max((time_alone(seeds, i, args.seed) for _, i in total.slowest), default=0.0)
    result = _result(total, args, seeds, elapsed, hang, max_rss, round(retimed, 6))
    emit(document("fuzz_decoder", [result]), args.out)
    return 1 if total.crashes or hang else 0


if __name__ == "__main__":
    sys.exit(main())
