"""Running mutated captures through the dataset loaders and tallying what happened.

Each mutant capture is written to a scratch folder and read with
:func:`csgs_codec.train.datasets.load_dataset` (masks read, none made) and, for the layouts
with a camera file, :func:`csgs_codec.scene.cameras_io.load_cameras`, with the heap traced.
Outcomes and tallies are those of :mod:`tests.fuzz.reader_campaign` (``ok``, ``typed``,
``crash``, ``timeout``); only the memory allowance differs (image decoding's fixed cost).
"""

from __future__ import annotations

import shutil
from collections import Counter
from pathlib import Path

from csgs_codec.scene.cameras_io import load_cameras
from csgs_codec.train.datasets import load_dataset
from tests.fuzz.loader_mutators import LoaderMutant, mutant_at
from tests.fuzz.loader_seeds import LoaderSeed
from tests.fuzz.reader_campaign import (
    MEMORY_FACTOR,
    FormatTally,
    Outcome,
    observe,
)
from tests.heap_peak import heap_tracing

MEMORY_ALLOWANCE = 16 << 20


class LoaderTally(FormatTally):
    """A layout's tally under the loaders' memory bound (64 x input bytes + 16 MiB)."""

    def add(self, o: Outcome) -> None:
        """Count outcome ``o`` (the over-bound count against :data:`MEMORY_ALLOWANCE`)."""
        over = self.over_memory_bound
        super().add(o)
        self.over_memory_bound = over + (o.peak_bytes > MEMORY_FACTOR * o.size
                                         + MEMORY_ALLOWANCE)


def _write(mutant: LoaderMutant, folder: Path) -> None:
    for name, data in mutant.files.items():
        target = folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)


def run_one(mutant: LoaderMutant, index: int, scratch: Path, time_limit: float = 5.0
            ) -> Outcome:
    """Load ``mutant`` from a capture folder under ``scratch`` (removed after)."""
    folder = scratch / f"in{index}" / "capture"
    folder.mkdir(parents=True)
    _write(mutant, folder)

    def read() -> None:
        load_dataset(folder, segment_missing=False)
        if mutant.seed.format != "llff":
            load_cameras(folder / mutant.seed.camera)

    try:
        kind, detail, seconds, peak = observe(read, time_limit)
    finally:
        shutil.rmtree(folder.parent, ignore_errors=True)
    return Outcome(index, mutant.seed.name, mutant.seed.format, kind, detail, seconds, peak,
                   mutant.size, mutant.operators)


def run_range(seeds: list[LoaderSeed], start: int, count: int, campaign: int, scratch: Path,
              time_limit: float = 5.0, *, tally: type[FormatTally] = LoaderTally,
              on_outcome=None) -> tuple[dict[str, FormatTally], Counter]:
    """Inputs ``start`` .. ``start + count - 1``: ({layout: tally}, operator counts);
    ``on_outcome(mutant, outcome)``, when given, sees every input."""
    tallies: dict[str, FormatTally] = {}
    operators: Counter = Counter()
    with heap_tracing():
        for index in range(start, start + count):
            mutant = mutant_at(seeds, index, campaign)
            outcome = run_one(mutant, index, scratch, time_limit)
            tallies.setdefault(outcome.format, tally()).add(outcome)
            operators.update(op.split(":")[0] for op in mutant.operators)
            if on_outcome is not None:
                on_outcome(mutant, outcome)
    return tallies, operators
