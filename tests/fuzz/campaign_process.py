"""A decoder fuzz campaign in a child process of its own (``python -m
tests.fuzz.campaign_process``), for the long campaign of ``-m slow``.

A segfault or an abort in the decoder then fails the test with the child's exit status and
its last output, instead of taking the pytest-xdist worker down with it; and the child has no
thread but its own while tracemalloc is switched (see tests/heap_peak.py for why that
matters on Python 3.11).
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
from pathlib import Path

from tests.fuzz.campaign import Summary, run_campaign
from tests.fuzz.seeds import build_seeds

REPO = Path(__file__).resolve().parents[2]


class CampaignProcessError(AssertionError):
    """The child process ended without a summary (crashed, killed or ran out of time)."""


def run_in_child(start: int, count: int, campaign_seed: int, trace_every: int,
                 folder: Path, timeout: float) -> Summary:
    """Run :func:`tests.fuzz.campaign.run_campaign` over freshly built seeds in a child
    process and return its summary; ``timeout`` in seconds (the child is killed after it).

    Raises:
        CampaignProcessError: when the child exits non-zero, is killed, or outlives
            ``timeout``, with its exit status and the end of its output.
    """
    out = folder / "summary.pickle"
    command = [sys.executable, "-m", "tests.fuzz.campaign_process", str(start), str(count),
               str(campaign_seed), str(trace_every), str(out)]
    try:
        done = subprocess.run(command, cwd=REPO, capture_output=True, text=True,
                              timeout=timeout, env=os.environ.copy())
    except subprocess.TimeoutExpired as err:
        raise CampaignProcessError(f"campaign {start}..{start + count - 1} still running "
                                   f"after {timeout} s") from err
    if done.returncode != 0 or not out.is_file():
        raise CampaignProcessError(f"campaign child exited with status {done.returncode}: "
                                   f"{(done.stdout + done.stderr)[-3000:]}")
    return pickle.loads(out.read_bytes())


def main(argv: list[str] | None = None) -> int:
    """Child entry point: run the campaign and pickle its summary to the given path."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for name in ("start", "count", "campaign_seed", "trace_every"):
        parser.add_argument(name, type=int)
    parser.add_argument("out", type=Path)
    args = parser.parse_args(argv)
    summary = run_campaign(build_seeds(), args.start, args.count, args.campaign_seed,
                           args.trace_every)
    args.out.write_bytes(pickle.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
