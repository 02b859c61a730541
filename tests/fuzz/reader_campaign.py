"""Running mutated interchange files through the readers and tallying what happened.

Each mutant is written to a scratch folder under its seed's suffix (a SOG folder as its
members) and read with :func:`csgs_codec.interchange.read_interchange`, the path every
command takes, with the heap traced. An input ends in one of:

* ``ok``: read (a valid scene);
* ``typed``: a :class:`~csgs_codec.errors.CsgsError` (the class name is tallied);
* ``crash``: any other exception (RecursionError, MemoryError, ValueError, ...);
* ``timeout``: still running after the time limit (a SIGALRM ends it; main thread only).
"""

from __future__ import annotations

import contextlib
import shutil
import signal
import threading
import time
import traceback
import warnings
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from csgs_codec.errors import CsgsError
from csgs_codec.interchange import read_interchange
from tests.fuzz.reader_mutators import Mutant, mutant_at
from tests.fuzz.reader_seeds import ReaderSeed
from tests.heap_peak import heap_peak, heap_tracing

#: The heap a reader may use: this many times the input's bytes, plus the allowance (the
#: fixed cost of imports and small tables).
MEMORY_FACTOR = 64
MEMORY_ALLOWANCE = 4 << 20
#: Inputs slower than this (seconds) are listed.
SLOW_SECONDS = 1.0


class InputTimeout(BaseException):
    """Raised by the alarm when one input runs past its limit (a BaseException, so that no
    reader's ``except Exception`` swallows it)."""


@dataclass
class Outcome:
    """What reading one mutant did."""

    index: int
    seed: str
    format: str
    kind: str  # "ok", "typed", "crash" or "timeout"
    detail: str
    seconds: float
    peak_bytes: int
    size: int
    operators: tuple[str, ...]


@dataclass
class FormatTally:
    """Counts for one format."""

    inputs: int = 0
    ok: int = 0
    typed: int = 0
    crashes: int = 0
    timeouts: int = 0
    over_memory_bound: int = 0
    errors: Counter = field(default_factory=Counter)
    max_seconds: float = 0.0
    max_seconds_index: int = -1
    max_peak_ratio: float = 0.0
    max_peak_bytes: int = 0
    max_peak_index: int = -1
    crash_examples: list = field(default_factory=list)
    slow: list = field(default_factory=list)

    def add(self, o: Outcome) -> None:
        """Count outcome ``o``."""
        self.inputs += 1
        if o.kind == "ok":
            self.ok += 1
        elif o.kind == "typed":
            self.typed += 1
            self.errors[o.detail.split(":", 1)[0]] += 1
        elif o.kind == "timeout":
            self.timeouts += 1
        else:
            self.crashes += 1
        if o.kind in ("crash", "timeout") and len(self.crash_examples) < 5:
            self.crash_examples.append({"index": o.index, "seed": o.seed, "detail": o.detail,
                                        "operators": list(o.operators)})
        if o.seconds > self.max_seconds:
            self.max_seconds, self.max_seconds_index = o.seconds, o.index
        if o.seconds > SLOW_SECONDS and len(self.slow) < 20:
            self.slow.append({"index": o.index, "seed": o.seed, "seconds": round(o.seconds, 3)})
        ratio = o.peak_bytes / max(o.size, 1)
        if ratio > self.max_peak_ratio:
            self.max_peak_ratio, self.max_peak_index = ratio, o.index
        self.max_peak_bytes = max(self.max_peak_bytes, o.peak_bytes)
        if o.peak_bytes > MEMORY_FACTOR * o.size + MEMORY_ALLOWANCE:
            self.over_memory_bound += 1

    def merge(self, other: FormatTally) -> None:
        """Add ``other``'s counts to these."""
        for name in ("inputs", "ok", "typed", "crashes", "timeouts", "over_memory_bound"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.errors.update(other.errors)
        if other.max_seconds > self.max_seconds:
            self.max_seconds, self.max_seconds_index = other.max_seconds, other.max_seconds_index
        if other.max_peak_ratio > self.max_peak_ratio:
            self.max_peak_ratio, self.max_peak_index = other.max_peak_ratio, other.max_peak_index
        self.max_peak_bytes = max(self.max_peak_bytes, other.max_peak_bytes)
        self.crash_examples = (self.crash_examples + other.crash_examples)[:5]
        self.slow = (self.slow + other.slow)[:20]


def _write(mutant: Mutant, folder: Path) -> Path:
    """The mutant as a file (or SOG folder) under ``folder``; returns its path."""
    if mutant.members:
        target = folder / "scene_sog"
        target.mkdir()
        for name, data in mutant.members.items():
            (target / name).write_bytes(data)
        return target
    target = folder / f"scene{mutant.seed.suffix}"
    target.write_bytes(mutant.data)
    return target


def _alarm(signum, frame):
    raise InputTimeout


@contextlib.contextmanager
def _time_limit(seconds: float):
    """Raise :class:`InputTimeout` in the block after ``seconds`` (SIGALRM; no limit when
    ``seconds`` is 0 or outside the main thread, e.g. under pytest-timeout, which uses the
    same signal)."""
    if not seconds or threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def observe(read: Callable[[], object], time_limit: float
            ) -> tuple[str, str, float, int]:
    """(kind, detail, seconds, peak traced heap bytes) of ``read()`` run under the alarm of
    ``time_limit`` seconds with warnings silenced: kind "ok", "typed" (a CsgsError), "timeout"
    or "crash" (any other exception, named with its last frame)."""
    kind, detail = "ok", ""
    began = time.perf_counter()
    try:
        with heap_peak() as peak, warnings.catch_warnings(), _time_limit(time_limit):
            warnings.simplefilter("ignore")
            read()
    except CsgsError as err:
        kind, detail = "typed", f"{type(err).__name__}: {err}"
    except InputTimeout:
        kind, detail = "timeout", f"no result after {time_limit} s"
    except Exception as exc:  # noqa: BLE001 - a crash is what the campaign looks for
        frame = traceback.extract_tb(exc.__traceback__)[-1]
        kind = "crash"
        detail = (f"{type(exc).__name__}: {str(exc)[:200]} at {Path(frame.filename).name}:"
                  f"{frame.lineno}")
    return kind, detail, time.perf_counter() - began, peak.bytes


def run_one(mutant: Mutant, index: int, scratch: Path, time_limit: float = 10.0) -> Outcome:
    """Read ``mutant`` from a file under ``scratch`` (emptied after) and say how it went."""
    folder = scratch / f"in{index}"
    folder.mkdir(parents=True)
    path = _write(mutant, folder)
    try:
        kind, detail, seconds, peak = observe(lambda: read_interchange(path), time_limit)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return Outcome(index, mutant.seed.name, mutant.seed.format, kind, detail, seconds, peak,
                   mutant.size, mutant.operators)


def run_range(seeds: list[ReaderSeed], start: int, count: int, campaign: int, scratch: Path,
              time_limit: float = 10.0, *, tally: type[FormatTally] = FormatTally,
              on_outcome=None) -> tuple[dict[str, FormatTally], Counter]:
    """Inputs ``start`` .. ``start + count - 1``: ({format: tally}, operator counts).
    ``tally``: the class that counts a format's outcomes; ``on_outcome(mutant, outcome)``,
    when given, sees every input (to keep the crashes, say)."""
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
