"""Tests of the benchmark helpers (peer codec wrappers)."""
