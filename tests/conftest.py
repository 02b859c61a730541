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


@pytest.fixture(scope="session")
def default_encoding(tmp_path_factory):
    """``default_encoding(source) -> (path, EncodeResult)``: ``Encoder()`` with its default
    settings on the scene file ``source`` (what `csgs encode SOURCE` writes, checked in
    tests/cli/test_codec_cli.py), encoded once per session and written to ``path``, so the
    round-trip, JavaScript and browser tests of what users make share one encode."""
    from csgs_codec import Encoder
    from csgs_codec.scene_files import read_scene

    folder = tmp_path_factory.mktemp("default_encodings")
    made: dict[str, tuple[Path, object]] = {}

    def encode(source: Path):
        key = str(Path(source).resolve())
        if key not in made:
            scene, _ = read_scene(source)
            result = Encoder().encode_with_report(scene)
            path = folder / str(len(made)) / f"{Path(source).stem}.csgs"
            path.parent.mkdir()
            path.write_bytes(result.data)
            made[key] = (path, result)
        return made[key]

    return encode


@pytest.fixture(scope="session")
def default_encode(tmp_path_factory, default_encoding):
    """``default_encode(source, *flags) -> Path``: the file ``csgs encode SOURCE -o OUT
    [FLAGS]`` writes (the command itself, in this process; without flags the session's
    :func:`default_encoding`), made once per session and source and flags."""
    from csgs_cli.main import main

    folder = tmp_path_factory.mktemp("default_encodes")
    made: dict[tuple, Path] = {}

    def encode(source: Path, *flags: str) -> Path:
        if not flags:
            return default_encoding(source)[0]
        key = (str(Path(source).resolve()), flags)
        if key not in made:
            out = folder / str(len(made)) / f"{Path(source).stem}.csgs"
            out.parent.mkdir()
            code = main(["encode", str(source), "-o", str(out), "--quiet", *flags])
            assert code == 0, f"csgs encode {source} {' '.join(flags)} exited with {code}"
            made[key] = out
        return made[key]

    return encode


def pytest_collection_modifyitems(config, items):
    """Skip `gpu` tests when torch sees no CUDA device (torch is imported only when a `gpu`
    test was collected, so that collection stays fast)."""
    if not any("gpu" in item.keywords for item in items):
        return
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
