"""What every benchmark script shares: the machine description and the JSON document."""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

SCHEMA = "csgs-bench/1"
REPO = Path(__file__).resolve().parents[1]
SCENES = REPO.parent / "shared" / "data" / "scenes"
#: Scenes that are full-precision training outputs; the others were decoded from a
#: compressed format (see ../shared/data/README.md), which flatters that format's re-encode.
FULL_PRECISION = {"donut", "fruit_drops", "leica_sofort_top8192", "yashica_t4_top8192"}


def held_out_views(scene, width: int, height: int) -> list:
    """16 orbit views at 20 degrees and 12 at 45 degrees elevation: views no encoder setting
    renders (the default viewing distribution is a sphere of directions at three
    distances), so render-aware encodes are scored where they did not allocate."""
    from csgs_codec.scene.orbit import orbit_cameras

    return (orbit_cameras(scene, 16, width=width, height=height, elevation_deg=20)
            + orbit_cameras(scene, 12, width=width, height=height, elevation_deg=45))


def best_of(repeat: int, run) -> tuple[float, object]:
    """(fastest wall seconds of ``repeat`` calls of ``run``, the last call's result)."""
    best, result = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        result = run()
        best = min(best, time.perf_counter() - start)
    return best, result


def machine() -> dict:
    """CPU count, platform and interpreter of this machine."""
    return {"cpus": os.cpu_count(), "platform": platform.platform(),
            "python": sys.version.split()[0], "processor": platform.processor()}


def document(benchmark: str, results: list[dict], **extra) -> dict:
    """A csgs-bench/1 document."""
    return {"schema": SCHEMA, "benchmark": benchmark, "machine": machine(), **extra,
            "results": results}


def emit(doc: dict, out: str | None) -> None:
    """Print ``doc`` as JSON, or write it to ``out``."""
    text = json.dumps(doc, indent=2, default=_plain)
    if out:
        Path(out).write_text(text + "\n")
    else:
        print(text)


def _plain(value):
    if hasattr(value, "item"):
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)


def save_failing_inputs(folder: Path | None, inputs) -> None:
    """Write each ``(name, data, info)`` of ``inputs`` to ``folder`` as ``name.csgs`` with
    ``info`` (a JSON-able dict) in ``name.json`` beside it; nothing when ``folder`` is None."""
    if folder is None:
        return
    folder.mkdir(parents=True, exist_ok=True)
    for name, data, info in inputs:
        (folder / f"{name}.csgs").write_bytes(data)
        (folder / f"{name}.json").write_text(json.dumps(info, indent=2) + "\n")
