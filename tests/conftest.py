"""Shared test fixtures: paths to the shared real scenes and the bundled sample."""

from __future__ import annotations

import fcntl
import hashlib
import os
import pickle
import subprocess
from contextlib import contextmanager
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
SCENES = SHARED_DATA / "scenes"
FIXTURES = SHARED_DATA / "fixtures"
SAMPLE = REPO / "samples" / "donut.ply"
#: Small fixtures copied into the repository (tests/data/fixtures/README.md).
REPO_FIXTURES = REPO / "tests" / "data" / "fixtures"

# A Python a test starts (the CLI, a benchmark, a training run) prints its stack when a
# signal kills it; without this a crash in a subprocess reports only "returncode -11".
os.environ.setdefault("PYTHONFAULTHANDLER", "1")


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


def _shared_folder(tmp_path_factory, name: str) -> Path:
    """A folder every pytest-xdist worker of this run sees (the parent of the workers' own
    temporary folders), or this process's temporary folder when there are no workers."""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    folder = root / name
    folder.mkdir(exist_ok=True)
    return folder


@contextmanager
def _held(lock_path: Path):
    """Hold an exclusive lock on ``lock_path`` (a file) while the block runs, so a worker
    that wants an encode another worker is making waits for it instead of repeating it."""
    with open(lock_path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


@pytest.fixture(scope="session")
def default_encoding(tmp_path_factory):
    """``default_encoding(source) -> (path, EncodeReport)``: ``Encoder()`` with its default
    settings on the scene file ``source`` (what `csgs encode SOURCE` writes, checked in
    tests/cli/test_codec_cli.py), encoded once per test run and written to ``path``, so the
    round-trip, JavaScript and browser tests of what users make share one encode. Workers
    share it through a folder keyed by the source file's bytes (the encoder is
    deterministic: tests/codec/test_codec_determinism.py)."""
    folder = _shared_folder(tmp_path_factory, "default_encodings")
    made: dict[str, tuple[Path, object]] = {}

    def encode(source: Path):
        key = hashlib.sha256(Path(source).read_bytes()).hexdigest()[:20]
        if key not in made:
            path = folder / key / f"{Path(source).stem}.csgs"
            report = folder / key / "result.pickle"
            with _held(folder / f"{key}.lock"):
                if report.exists():
                    result = pickle.loads(report.read_bytes())
                else:
                    from csgs_codec import Encoder
                    from csgs_codec.codec.files import read_scene

                    scene = read_scene(source)
                    result = Encoder().encode_with_report(scene)
                    path.parent.mkdir(exist_ok=True)
                    path.write_bytes(result.data)
                    report.write_bytes(pickle.dumps(result))
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


#: The test files that take longest (seconds of one worker each, measured on the 2-core
#: machine), in the order they start: `make test` hands whole files to its workers in
#: collection order (``--dist loadfile --no-loadscope-reorder``), so these go first and the
#: short files fill the gaps, and the two workers finish together. Files that share default
#: encodes (tests/conftest.py) are kept apart in the order, so one makes what the other reads
#: (tests/js/test_js_shared_scenes.py, which reads the repository SH-3 capture's encode that
#: tests/web/test_viewer_shared_scenes.py makes, is left to its place in collection order).
LONGEST_FIRST = (
    "tests/codec/test_codec_roundtrip.py",
    "tests/web/test_viewer_default_encodes.py",
    "tests/codec/test_view_pruning.py",
    "tests/web/test_viewer_browser.py",
    "tests/fuzz/test_decoder_fuzz.py",
    "tests/web/test_viewer_shared_scenes.py",
    "tests/codec/test_accepted_scenes_decode.py",
    "tests/tiles/test_parallel_tiles.py",
    "tests/web/test_server.py",
    "tests/cli/test_encode_flags.py",
    "tests/codec/test_step_allocation.py",
    "tests/codec/test_codec_determinism.py",
    "tests/tiles/test_tiled_codec.py",
    "tests/train/test_pipeline.py",
    "tests/cli/test_anchor_cli.py",
    "tests/js/test_js_decoder.py",
    "tests/stability/test_fit_stability.py",
)


def pytest_collection_modifyitems(config, items):
    """Run :data:`LONGEST_FIRST` first (other files keep their order), and skip `gpu` tests
    when torch sees no CUDA device (torch is imported only when a `gpu` test was
    collected, so that collection stays fast)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))
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


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Add what a failed ``subprocess.run(..., check=True)`` printed to the test's report
    (CalledProcessError's message names only the exit status)."""
    outcome = yield
    error = call.excinfo.value if call.excinfo is not None else None
    if isinstance(error, subprocess.CalledProcessError):
        report = outcome.get_result()
        for name, text in (("stdout", error.stdout), ("stderr", error.stderr)):
            if text:
                text = text.decode(errors="replace") if isinstance(text, bytes) else text
                report.sections.append((f"subprocess {name}", text[-4000:]))
