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
