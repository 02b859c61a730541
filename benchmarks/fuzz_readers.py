"""Fuzz the interchange readers (PLY binary and ASCII, compressed PLY, SPZ, SOG, GLB, .splat,
.ksplat) with mutated real files and report crashes, time and memory per format.

    python benchmarks/fuzz_readers.py --inputs 100000 [--workers 2] [--seed 0] [--start I]
        [--out fuzz.json] [--batch 1000] [--time-limit S] [--crash-dir DIR]

Input i is mutant i of the reproducible sequence of tests/fuzz/reader_mutators.py
(``mutant_at(reader_seeds(), i, seed)`` rebuilds it alone): a format drawn uniformly, one of
its seeds (the fixtures in tests/data/formats and two ASCII PLYs made from them), then bit
flips, byte sets, large 32-bit values, truncation, splices, PLY header-line and ASCII token
edits, SPZ payload edits inside the gzip stream, SOG member edits, JSON edits of a GLB's
JSON chunk or a SOG meta.json. Each is written to a scratch file and read with
``read_interchange``, the heap traced. Per format the JSON (schema csgs-bench/1, rewritten
after every batch) gives the inputs, files read (``parsed_ok``), typed errors (by class),
``crashes`` (any other exception, with up to five examples), ``timeouts`` (inputs still
running after ``--time-limit`` seconds, ended by an alarm and counted, never skipped), the
slowest input and the largest traced heap peak as a ratio to the input's bytes (inputs of at
least 1 KiB) and as a share of the bound the tests use (64 x input bytes + 4 MiB).
Crashing inputs are written to ``--crash-dir``. Exit status 1 when any input crashed or
timed out.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_common import document, emit  # noqa: E402

from tests.fuzz.reader_campaign import (  # noqa: E402
    MEMORY_ALLOWANCE,
    MEMORY_FACTOR,
    SLOW_SECONDS,
    FormatTally,
    run_range,
)
from tests.fuzz.reader_seeds import FORMATS, reader_seeds  # noqa: E402

#: Inputs smaller than this are left out of the heap ratio (a few bytes of input against
#: the fixed cost of a read says nothing).
RATIO_MIN_BYTES = 1024

_SEEDS: list = []
_CAMPAIGN = 0
_TIME_LIMIT = 10.0
_SCRATCH: Path | None = None
_CRASH_DIR: Path | None = None


def _init_worker(campaign: int, time_limit: float, crash_dir: Path | None,
                 scratch: Path) -> None:
    global _SEEDS, _CAMPAIGN, _TIME_LIMIT, _SCRATCH, _CRASH_DIR
    _SEEDS, _CAMPAIGN, _TIME_LIMIT, _CRASH_DIR = reader_seeds(), campaign, time_limit, crash_dir
    _SCRATCH = scratch / f"worker{os.getpid()}"


class HeapFigures:
    """Mixin for a campaign's tally class: also tracks the largest heap ratio of inputs of
    RATIO_MIN_BYTES+ and the largest share of the memory bound (``allowance``: its bytes
    beyond MEMORY_FACTOR x input)."""

    allowance = MEMORY_ALLOWANCE

    def __init__(self) -> None:
        super().__init__()
        self.ratio_large, self.ratio_large_index, self.bound_share = 0.0, -1, 0.0

    def add(self, o) -> None:
        super().add(o)
        if o.size >= RATIO_MIN_BYTES and o.peak_bytes / o.size > self.ratio_large:
            self.ratio_large, self.ratio_large_index = o.peak_bytes / o.size, o.index
        self.bound_share = max(self.bound_share,
                               o.peak_bytes / (MEMORY_FACTOR * o.size + self.allowance))

    def merge(self, other) -> None:
        super().merge(other)
        if other.ratio_large > self.ratio_large:
            self.ratio_large, self.ratio_large_index = other.ratio_large, other.ratio_large_index
        self.bound_share = max(self.bound_share, other.bound_share)


class _Tally(HeapFigures, FormatTally):
    """A format's tally with the heap figures."""


def _save_crash(mutant, outcome) -> None:
    if _CRASH_DIR is None or outcome.kind not in ("crash", "timeout"):
        return
    _CRASH_DIR.mkdir(parents=True, exist_ok=True)
    stem = _CRASH_DIR / f"crash_{outcome.index}"
    if mutant.members:
        stem.mkdir(exist_ok=True)
        for name, data in mutant.members.items():
            (stem / name).write_bytes(data)
    else:
        stem.with_suffix(mutant.seed.suffix or ".bin").write_bytes(mutant.data)
    stem.with_suffix(".json").write_text(json.dumps(
        {"index": outcome.index, "seed": outcome.seed, "detail": outcome.detail,
         "operators": list(outcome.operators)}, indent=2) + "\n")


def _run_batch(bounds: tuple[int, int]) -> tuple[dict[str, _Tally], Counter]:
    start, count = bounds
    return run_range(_SEEDS, start, count, _CAMPAIGN, _SCRATCH, _TIME_LIMIT, tally=_Tally,
                     on_outcome=_save_crash)


def _format_row(name: str, t: _Tally) -> dict:
    return {
        "format": name,
        "inputs": t.inputs,
        "parsed_ok": t.ok,
        "typed_errors": t.typed,
        "typed_errors_by_class": dict(t.errors),
        "crashes": t.crashes,
        "timeouts": t.timeouts,
        "crash_examples": t.crash_examples,
        "max_seconds_per_input": round(t.max_seconds, 6),
        "slowest_input": t.max_seconds_index,
        "slow_inputs": t.slow,
        "max_peak_heap_bytes": t.max_peak_bytes,
        "max_peak_heap_ratio": round(t.ratio_large, 3),
        "max_peak_heap_ratio_input": t.ratio_large_index,
        "max_share_of_memory_bound": round(t.bound_share, 4),
        "over_memory_bound": t.over_memory_bound,
    }


def _result(tallies: dict[str, _Tally], operators: Counter, args, elapsed: float,
            hang: str | None) -> dict:
    total = sum(t.inputs for t in tallies.values())
    rows = [_format_row(f, tallies[f]) for f in FORMATS if f in tallies]
    return {
        "requested_inputs": args.inputs,
        "first_input": args.start,
        "inputs": total,
        "complete": total == args.inputs and hang is None,
        "hang": hang,
        "crashes": sum(t.crashes for t in tallies.values()),
        "timeouts": sum(t.timeouts for t in tallies.values()),
        "typed_errors": sum(t.typed for t in tallies.values()),
        "parsed_ok": sum(t.ok for t in tallies.values()),
        "max_seconds_per_input": max((r["max_seconds_per_input"] for r in rows), default=0.0),
        "max_peak_heap_ratio": max((r["max_peak_heap_ratio"] for r in rows), default=0.0),
        "max_share_of_memory_bound": max((r["max_share_of_memory_bound"] for r in rows),
                                         default=0.0),
        "memory_bound": f"{MEMORY_FACTOR} x input bytes + {MEMORY_ALLOWANCE} bytes",
        "heap_ratio_min_input_bytes": RATIO_MIN_BYTES,
        "slow_seconds": SLOW_SECONDS,
        "time_limit_s": args.time_limit,
        "formats": rows,
        "operators": dict(operators.most_common()),
        "campaign_seed": args.seed,
        "workers": args.workers,
        "seeds": [{"name": s.name, "format": s.format, "bytes": s.size} for s in reader_seeds()],
        "elapsed_s": round(elapsed, 1),
        "inputs_per_s": round(total / max(elapsed, 1e-9), 1),
    }


def campaign_arguments(description: str, batch: int, time_limit: float) -> argparse.Namespace:
    """The options every fuzz campaign script takes (their defaults for ``batch`` inputs per
    batch and ``time_limit`` seconds per input)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--inputs", type=int, default=10_000)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0, help="campaign seed")
    parser.add_argument("--start", type=int, default=0, help="first input index")
    parser.add_argument("--batch", type=int, default=batch, help="inputs per batch")
    parser.add_argument("--time-limit", type=float, default=time_limit,
                        help="seconds one input may run before it counts as a timeout")
    parser.add_argument("--out", help="write the JSON here (rewritten after every batch)")
    parser.add_argument("--crash-dir", type=Path, help="write crashing inputs here")
    return parser.parse_args()


def run_campaign(args: argparse.Namespace, benchmark: str, init_worker, run_batch,
                 tally: type, result) -> dict:
    """Run the inputs ``args`` asks for in batches on forked workers (``init_worker(seed,
    time_limit, crash_dir, scratch)`` starts each, ``run_batch((start, count))`` returns a
    batch's ({name: tally}, operator Counter)), merging into ``tally`` instances and writing
    ``result(tallies, operators, args, elapsed, hang)`` as the ``benchmark`` JSON after every
    batch; a batch past its time ends the run as a hang. Returns the final result row."""
    batches = [(s, min(args.batch, args.start + args.inputs - s))
               for s in range(args.start, args.start + args.inputs, args.batch)]
    tallies: dict = {}
    operators: Counter = Counter()
    hang = None
    began = time.perf_counter()
    ctx = multiprocessing.get_context("fork")
    root = "/dev/shm" if os.path.isdir("/dev/shm") else None  # scratch files in memory
    with tempfile.TemporaryDirectory(prefix=f"csgs_{benchmark}_", dir=root) as scratch, \
            ctx.Pool(args.workers, init_worker,
                     (args.seed, args.time_limit, args.crash_dir, Path(scratch))) as pool:
        pending = [(b, pool.apply_async(run_batch, (b,))) for b in batches]
        for bounds, job in pending:
            try:
                part, ops = job.get(timeout=args.batch * (args.time_limit + 1) + 60)
            except multiprocessing.TimeoutError:
                hang = f"batch of inputs {bounds[0]}..{sum(bounds) - 1} did not finish"
                pool.terminate()
                break
            for name, counted in part.items():
                tallies.setdefault(name, tally()).merge(counted)
            operators.update(ops)
            if args.out:
                emit(document(benchmark, [result(tallies, operators, args,
                                                 time.perf_counter() - began, hang)]),
                     args.out)
    row = result(tallies, operators, args, time.perf_counter() - began, hang)
    emit(document(benchmark, [row]), args.out)
    return row


def main() -> int:
    """Run the campaign; exit status 1 when any input crashed, timed out or a batch hung."""
    args = campaign_arguments(__doc__.splitlines()[0], batch=1000, time_limit=10.0)
    row = run_campaign(args, "fuzz_readers", _init_worker, _run_batch, _Tally, _result)
    return 1 if row["crashes"] or row["timeouts"] or row["hang"] else 0


if __name__ == "__main__":
    sys.exit(main())
