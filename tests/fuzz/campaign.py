"""A fuzz campaign: inputs ``start .. start + count - 1`` of a reproducible mutant sequence.

Input ``i`` of campaign seed ``s`` is ``mutate(seed file, random.Random(s * 2^32 + i), ...)``
with the seed file drawn by weight from the same generator, so any input can be rebuilt from
its index alone (:func:`mutant_at`) and a campaign can be split across processes by index.
"""

from __future__ import annotations

import heapq
import random
import tracemalloc
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

from tests.fuzz.mutators import Mutant, mutate
from tests.fuzz.oracle import Outcome, memory_bound, run_decoder
from tests.fuzz.seeds import Seed

#: How many of the slowest inputs a summary remembers (to time them again, alone).
SLOWEST_KEPT = 10


@dataclass(frozen=True)
class Crash:
    """One misbehaving input: where it came from, what happened and its bytes."""

    index: int
    seed: str
    operators: tuple[str, ...]
    detail: str
    data: bytes


@dataclass
class Summary:
    """Totals of a campaign (or a part of one); parts add up with :meth:`merge`.

    Attributes:
        inputs: inputs decoded.
        traced: inputs whose heap peak was measured.
        outcomes: count per outcome kind ("ok", "FormatError", "crash", ...).
        stages: count of allowed errors by where they were raised: "crc" (a CRC check),
            "container" (header, TOC or frame checks) or "payload" (a chunk decoder).
        operators: count of each mutation operator used.
        slowest: the :data:`SLOWEST_KEPT` slowest decodes as (seconds, index), slowest first.
        max_memory_ratio, max_memory_index: largest heap peak per input byte and its index.
        max_bound_use: largest heap peak as a share of its :func:`memory_bound` (<= 1 passes).
        max_peak_bytes: largest heap peak in bytes.
        crashes: the misbehaving inputs.
    """

    inputs: int = 0
    traced: int = 0
    outcomes: Counter = field(default_factory=Counter)
    stages: Counter = field(default_factory=Counter)
    operators: Counter = field(default_factory=Counter)
    slowest: list[tuple[float, int]] = field(default_factory=list)
    max_memory_ratio: float = 0.0
    max_memory_index: int = -1
    max_bound_use: float = 0.0
    max_peak_bytes: int = 0
    crashes: list[Crash] = field(default_factory=list)

    def add(self, index: int, mutant: Mutant, outcome: Outcome) -> None:
        """Count one decoded input."""
        self.inputs += 1
        self.traced += outcome.traced
        self.outcomes[outcome.kind] += 1
        if outcome.stage is not None:
            self.stages[outcome.stage] += 1
        self.operators.update(op.split(":")[0] for op in mutant.operators)
        self._keep_slowest([(outcome.seconds, index)])
        if outcome.memory_ratio > self.max_memory_ratio:
            self.max_memory_ratio, self.max_memory_index = outcome.memory_ratio, index
        self.max_bound_use = max(self.max_bound_use,
                                 outcome.peak_bytes / memory_bound(outcome.input_bytes))
        self.max_peak_bytes = max(self.max_peak_bytes, outcome.peak_bytes)
        if outcome.crashed:
            self.crashes.append(Crash(index, mutant.seed, mutant.operators, outcome.detail,
                                      mutant.data))

    def merge(self, other: Summary) -> None:
        """Add ``other``'s totals to these."""
        self.inputs += other.inputs
        self.traced += other.traced
        self.outcomes.update(other.outcomes)
        self.stages.update(other.stages)
        self.operators.update(other.operators)
        self._keep_slowest(other.slowest)
        if other.max_memory_ratio > self.max_memory_ratio:
            self.max_memory_ratio = other.max_memory_ratio
            self.max_memory_index = other.max_memory_index
        self.max_bound_use = max(self.max_bound_use, other.max_bound_use)
        self.max_peak_bytes = max(self.max_peak_bytes, other.max_peak_bytes)
        self.crashes.extend(other.crashes)

    @property
    def max_seconds(self) -> float:
        """Wall time of the slowest decode (0 when nothing ran)."""
        return self.slowest[0][0] if self.slowest else 0.0

    def _keep_slowest(self, entries: list[tuple[float, int]]) -> None:
        self.slowest = heapq.nlargest(SLOWEST_KEPT, self.slowest + list(entries))


def mutant_at(seeds: Sequence[Seed], index: int, campaign_seed: int = 0) -> Mutant:
    """Input ``index`` of the campaign ``campaign_seed`` over ``seeds``."""
    rng = random.Random((campaign_seed << 32) + index)
    seed = rng.choices(seeds, weights=[s.weight for s in seeds])[0]
    return mutate(seed, rng, seeds)


def _set_tracing(on: bool) -> None:
    if on and not tracemalloc.is_tracing():
        tracemalloc.start()
    elif not on and tracemalloc.is_tracing():
        tracemalloc.stop()


def run_campaign(seeds: Sequence[Seed], start: int, count: int, campaign_seed: int = 0,
                 trace_every: int = 1) -> Summary:
    """Decode inputs ``start .. start + count - 1`` under the oracle and total them.

    Args:
        trace_every: measure the heap peak of inputs whose index is a multiple of this (1:
            all); the others decode about twice as fast, unmeasured.
    """
    summary = Summary()
    indices = range(start, start + count)
    untraced = [i for i in indices if i % trace_every != 0]
    traced = [i for i in indices if i % trace_every == 0]
    tracing = tracemalloc.is_tracing()
    # Tracing is switched once per group, never per input (why: tests/heap_peak.py); the
    # long campaign's 25,000 switches once ended in a segfault that took a CI worker down.
    try:
        for group, trace in ((untraced, False), (traced, True)):
            _set_tracing(trace)
            for index in group:
                mutant = mutant_at(seeds, index, campaign_seed)
                summary.add(index, mutant, run_decoder(mutant.data, trace))
    finally:
        _set_tracing(tracing)
    summary.crashes.sort(key=lambda crash: crash.index)
    return summary


def time_alone(seeds: Sequence[Seed], index: int, campaign_seed: int = 0,
               repeats: int = 3) -> float:
    """Fastest of ``repeats`` untraced decodes of input ``index`` (seconds): its time without
    the tracing overhead and with less noise from other processes."""
    data = mutant_at(seeds, index, campaign_seed).data
    _set_tracing(False)
    return min(run_decoder(data, trace=False).seconds for _ in range(repeats))
