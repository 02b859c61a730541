"""Mutated interchange files (the mutators of benchmarks/fuzz_readers.py over every format
csgs reads) only ever raise typed csgs errors, within the heap bound of 64 x input bytes +
4 MiB. A few hundred inputs run in the default suite; the slow test runs twenty thousand."""

from __future__ import annotations

from collections import Counter

import pytest

from tests.fuzz.reader_campaign import run_range
from tests.fuzz.reader_mutators import mutant_at
from tests.fuzz.reader_seeds import FORMATS, reader_seeds

SEEDS = reader_seeds()


def _assert_clean(tallies) -> None:
    problems = {name: t.crash_examples for name, t in tallies.items()
                if t.crashes or t.timeouts or t.over_memory_bound}
    assert problems == {}


def test_mutants_are_a_pure_function_of_seed_and_index():
    for index in (0, 7, 12345):
        a, b = mutant_at(SEEDS, index, 3), mutant_at(SEEDS, index, 3)
        assert (a.data, a.members, a.operators) == (b.data, b.members, b.operators)
    assert mutant_at(SEEDS, 1, 0).data != mutant_at(SEEDS, 1, 1).data


def test_every_format_is_drawn():
    drawn = Counter(mutant_at(SEEDS, i).seed.format for i in range(400))
    assert set(drawn) == set(FORMATS)
    assert min(drawn.values()) >= 25


def test_a_few_hundred_mutants_only_raise_typed_errors(tmp_path):
    tallies, _ = run_range(SEEDS, 0, 400, campaign=0, scratch=tmp_path, time_limit=0)
    assert sum(t.inputs for t in tallies.values()) == 400
    _assert_clean(tallies)
    # The mutants reach past the first checks: some still read, most fail typed.
    assert sum(t.ok for t in tallies.values()) > 20
    assert sum(t.typed for t in tallies.values()) > 200


@pytest.mark.slow
def test_twenty_thousand_mutants_only_raise_typed_errors(tmp_path):
    tallies, _ = run_range(SEEDS, 400, 20_000, campaign=1, scratch=tmp_path, time_limit=0)
    _assert_clean(tallies)
