"""Conformance vectors under ``spec/vectors/``: generators, one module per vector family.

Each module ``tests.conformance.<family>`` defines ``generate(out_dir: pathlib.Path)``,
which writes that family's vectors into ``out_dir`` (= ``spec/vectors/<family>/``). Vectors
are regenerated only through ``python -m tests.conformance --regenerate``; tests read them.
"""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

#: The repository's vector folder (valid when running from a source checkout).
VECTORS_DIR = Path(__file__).resolve().parents[2] / "spec" / "vectors"
#: Scene vectors written by drafts before spec revision 21 (spec/CHANGES.md), whose float
#: stream channel records use the retired mode numbers. Vectors are never deleted: these stay
#: as landed (tests/codec/test_scene_vectors.py checks each against its recorded SHA-256),
#: but they are not format 1.0 files, so no test decodes them as such. The ``*_r1`` files are
#: the first draft's vectors, whose names revision 21's vectors took over (their JSON keeps
#: the name they landed under).
RETIRED_SCENE_VECTORS = frozenset({
    "derived_steps_q5", "derived_steps_infinite_threshold", "donut_q3_r2", "donut_q7_r2",
    "semantic_small_r2", "three_points_sh3_q9_r2", "truncated_opacity_payload_r2",
    "donut_q3_r1", "donut_q7_r1", "three_points_sh3_q9_r1", "semantic_small_r1",
    "missing_opacity_chunk_r1", "truncated_dc_payload_r1", "truncated_label_payload_r1"})


def current(paths) -> list[Path]:
    """``paths`` without the retired scene vectors (by file stem), in order."""
    return [p for p in paths if Path(p).stem not in RETIRED_SCENE_VECTORS]


def families() -> list[str]:
    """Names of the vector families that have a generator module."""
    here = Path(__file__).parent
    return sorted(m.name for m in pkgutil.iter_modules([str(here)]) if not m.name.startswith("_"))


def regenerate(only: list[str] | None = None, root: Path = VECTORS_DIR) -> list[str]:
    """Run the generators (all, or those named in ``only``); returns the families written."""
    done = []
    for name in families():
        if only and name not in only:
            continue
        module = importlib.import_module(f"{__name__}.{name}")
        out_dir = root / name
        out_dir.mkdir(parents=True, exist_ok=True)
        module.generate(out_dir)
        done.append(name)
    return done
