"""Shared test fixtures: paths to the shared real scenes and the bundled sample."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
SCENES = SHARED_DATA / "scenes"
FIXTURES = SHARED_DATA / "fixtures"
SAMPLE = REPO / "samples" / "donut.ply"
#: Small fixtures copied into the repository (tests/data/fixtures/README.md).
REPO_FIXTURES = REPO / "tests" / "data" / "fixtures"


def shared_path(*parts: str) -> Path:
    """Path under ../shared/data, skipping the test when the shared data is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not present: {path}")
    return path


def fixture(name: str) -> Path:
    """A fixture PLY: the repository's copy, else ../shared/data/fixtures (skip if absent)."""
    local = REPO_FIXTURES / name
    return local if local.exists() else shared_path("fixtures", name)


def fixture_files() -> list[Path]:
    """Every fixture PLY present, the repository's copies first, each name once."""
    local = sorted(REPO_FIXTURES.glob("*.ply"))
    names = {p.name for p in local}
    return local + [p for p in sorted(FIXTURES.glob("*.ply")) if p.name not in names]


def pytest_collection_modifyitems(config, items):
    """Skip `gpu` tests when torch sees no CUDA device."""
    try:
        import torch

        has_gpu = torch.cuda.is_available()
    except Exception:  # pragma: no cover - torch missing
        has_gpu = False
    if has_gpu:
        return
    skip = pytest.mark.skip(reason="no CUDA GPU")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)
