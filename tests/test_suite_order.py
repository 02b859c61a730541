"""The suite's start order (tests/conftest.py LONGEST_FIRST) names files that exist, once
each: a renamed file would otherwise drop silently to the end of the run."""

from tests.conftest import LONGEST_FIRST, REPO


def test_the_longest_first_list_names_existing_test_files_once():
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)
    assert [name for name in LONGEST_FIRST if not (REPO / name).is_file()] == []
