"""Fuzz the dataset loaders (transforms.json, INRIA cameras.json, COLMAP text and binary,
LLFF poses_bounds.npy, with their images and masks) with mutated tiny real captures and
report crashes, time and memory per layout.

    python benchmarks/fuzz_loaders.py --inputs 10000 [--workers 2] [--seed 0] [--start I]
        [--out fuzz.json] [--batch 500] [--time-limit S] [--crash-dir DIR]

Input i is mutant i of the reproducible sequence of tests/fuzz/loader_mutators.py
(``mutant_at(loader_seeds(), i, seed)`` rebuilds it alone): a layout drawn uniformly, its
seed capture (3 views of 8x6 px with masks), then edits of one or two of its files: byte
operators, JSON value swaps (huge, negative, NaN, inf numbers, wrong types, deep nesting,
long strings, absolute and ../ paths), COLMAP token and image-name swaps, .npy header
edits, images and masks truncated, with a PNG size that lies or re-saved in another mode.
Each capture is written to a scratch folder and read with ``load_dataset`` (and
``load_cameras``), the heap traced. The JSON has the schema of fuzz_readers.py's (one row
per layout under ``formats``), the bound being 64 x input bytes + 16 MiB. Crashing inputs
are written to ``--crash-dir``. Exit status 1 when any input crashed or timed out.
"""

from __future__ import annotations

import json
import os
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from fuzz_readers import (  # noqa: E402
    RATIO_MIN_BYTES,
    HeapFigures,
    _format_row,
    campaign_arguments,
    run_campaign,
)

from tests.fuzz.loader_campaign import MEMORY_ALLOWANCE, LoaderTally, run_range  # noqa: E402
from tests.fuzz.loader_seeds import FORMATS, loader_seeds  # noqa: E402
from tests.fuzz.reader_campaign import MEMORY_FACTOR, SLOW_SECONDS  # noqa: E402

_CAMPAIGN = 0
_TIME_LIMIT = 5.0
_SCRATCH: Path | None = None
_CRASH_DIR: Path | None = None


def _init_worker(campaign: int, time_limit: float, crash_dir: Path | None,
                 scratch: Path) -> None:
    global _CAMPAIGN, _TIME_LIMIT, _SCRATCH, _CRASH_DIR
    _CAMPAIGN, _TIME_LIMIT, _CRASH_DIR = campaign, time_limit, crash_dir
    _SCRATCH = scratch / f"worker{os.getpid()}"


class _Tally(HeapFigures, LoaderTally):
    """A layout's tally with the heap figures, under the loaders' memory bound."""

    allowance = MEMORY_ALLOWANCE


def _save_crash(mutant, outcome) -> None:
    if _CRASH_DIR is None or outcome.kind not in ("crash", "timeout"):
        return
    stem = _CRASH_DIR / f"crash_{outcome.index}"
    for name, data in mutant.files.items():
        (stem / name).parent.mkdir(parents=True, exist_ok=True)
        (stem / name).write_bytes(data)
    stem.with_suffix(".json").write_text(json.dumps(
        {"index": outcome.index, "seed": outcome.seed, "detail": outcome.detail,
         "operators": list(outcome.operators)}, indent=2) + "\n")


def _run_batch(bounds: tuple[int, int]) -> tuple[dict[str, _Tally], Counter]:
    start, count = bounds
    return run_range(loader_seeds(), start, count, _CAMPAIGN, _SCRATCH, _TIME_LIMIT,
                     tally=_Tally, on_outcome=_save_crash)


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
        "max_peak_heap_bytes": max((r["max_peak_heap_bytes"] for r in rows), default=0),
        "max_peak_heap_ratio": max((r["max_peak_heap_ratio"] for r in rows), default=0.0),
        "max_share_of_memory_bound": max((r["max_share_of_memory_bound"] for r in rows),
                                         default=0.0),
        "over_memory_bound": sum(t.over_memory_bound for t in tallies.values()),
        "memory_bound": f"{MEMORY_FACTOR} x input bytes + {MEMORY_ALLOWANCE} bytes",
        "heap_ratio_min_input_bytes": RATIO_MIN_BYTES,
        "slow_seconds": SLOW_SECONDS,
        "time_limit_s": args.time_limit,
        "formats": rows,
        "operators": dict(operators.most_common()),
        "campaign_seed": args.seed,
        "workers": args.workers,
        "seeds": [{"name": s.name, "format": s.format, "bytes": s.size}
                  for s in loader_seeds()],
        "elapsed_s": round(elapsed, 1),
        "inputs_per_s": round(total / max(elapsed, 1e-9), 1),
    }


def main() -> int:
    """Run the campaign; exit status 1 when any input crashed, timed out or a batch hung."""
    args = campaign_arguments(__doc__.splitlines()[0], batch=500, time_limit=5.0)
    loader_seeds()  # made once, before the workers fork
    row = run_campaign(args, "fuzz_loaders", _init_worker, _run_batch, _Tally, _result)
    return 1 if row["crashes"] or row["timeouts"] or row["hang"] else 0


if __name__ == "__main__":
    sys.exit(main())
