"""Mutated captures (tests/fuzz/loader_mutators.py over every layout load_dataset reads) only
ever load or raise typed csgs errors, each within 5 s and the heap bound of 64 x input bytes
+ 16 MiB. Two hundred inputs run in the default suite; the slow test runs ten thousand."""

from __future__ import annotations

from collections import Counter

import pytest

from csgs_codec.train.datasets import load_dataset
from tests.fuzz.loader_campaign import run_range
from tests.fuzz.loader_mutators import mutant_at
from tests.fuzz.loader_seeds import FORMATS, loader_seeds

SEEDS = loader_seeds()


def _assert_clean(tallies) -> None:
    problems = {name: t.crash_examples for name, t in tallies.items()
                if t.crashes or t.timeouts or t.over_memory_bound}
    assert problems == {}


def test_every_seed_capture_loads_as_written(tmp_path):
    for seed in SEEDS:
        root = tmp_path / seed.name
        for name, data in seed.files.items():
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            (root / name).write_bytes(data)
        views = load_dataset(root, segment_missing=False)
        assert [(v.image.shape, v.mask.shape) for v in views] == [((6, 8, 3), (6, 8))] * 3


def test_mutants_are_a_pure_function_of_seed_and_index():
    for index in (0, 7, 12345):
        a, b = mutant_at(SEEDS, index, 3), mutant_at(SEEDS, index, 3)
        assert (a.files, a.operators) == (b.files, b.operators)
    assert mutant_at(SEEDS, 1, 0).files != mutant_at(SEEDS, 1, 1).files


def test_every_layout_is_drawn():
    drawn = Counter(mutant_at(SEEDS, i).seed.format for i in range(200))
    assert set(drawn) == set(FORMATS)
    assert min(drawn.values()) >= 20


def test_two_hundred_mutants_only_raise_typed_errors(tmp_path):
    tallies, _ = run_range(SEEDS, 0, 200, campaign=0, scratch=tmp_path, time_limit=5.0)
    assert sum(t.inputs for t in tallies.values()) == 200
    _assert_clean(tallies)
    # The mutants reach past the first checks: some still load, most fail typed.
    assert sum(t.ok for t in tallies.values()) > 15
    assert sum(t.typed for t in tallies.values()) > 100
    assert max(t.max_seconds for t in tallies.values()) < 5.0


@pytest.mark.slow
def test_ten_thousand_mutants_only_raise_typed_errors(tmp_path):
    tallies, _ = run_range(SEEDS, 200, 10_000, campaign=1, scratch=tmp_path, time_limit=5.0)
    _assert_clean(tallies)
