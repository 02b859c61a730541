"""The browser page streaming a file with levels of detail against the page reading the whole
file, both over a simulated link (issue #53): time and bytes to the first frame, and time
until the view has all the detail it wants.

    .venv/bin/python benchmarks/web_levels.py --levels-file L.csgs --whole-file W.csgs
        [--mbit 50] [--rounds 3] [--size 800x600] [--budget N] [--out FILE]
    .venv/bin/python benchmarks/web_levels.py --scene donut [--levels 3 --tile-size 8000]

``--levels-file`` is what `csgs encode --levels L` writes, ``--whole-file`` the same scene as
`csgs encode` writes it by default (one level); or ``--scene`` (donut: the sample; a shared
scene's name) encodes both here. Each file is served by csgs_codec.web.server paced at
``--mbit`` Mbit/s (every answer shares the link; the page's own scripts are not paced) and
opened ``rounds`` times in a fresh page (Debian chromium, software WebGL through SwiftShader,
this machine's CPU). Per round:

* the streamed file: ``first_frame_ms`` (navigation start to the first frame drawn),
  ``first_frame_bytes`` (scene bytes read by then: header, TOC, index and the coarsest
  level) and its share of the file, ``complete_ms`` (the frame holding every tile the page's
  cut wants for the default view, at the page's default 1.5 px and ``--budget``),
  ``complete_bytes``, the tiles drawn per level; and with ``lodpx=0.001`` (every level-0
  tile wanted: all the file's detail) ``all_detail_ms`` and its bytes;
* the whole file: ``first_frame_ms`` and ``color_frame_ms`` (all its detail).

Ratios are taken within the run: all-detail time of the streamed file over the whole-file
page's color frame (target <= 1.10), first frame in seconds (target <= 1.0 s) and bytes share
(target <= 5%).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_common import REPO, SCENES, document, emit  # noqa: E402

from csgs_codec import Encoder, read_ply  # noqa: E402
from csgs_codec.web.server import ViewerServer  # noqa: E402
from tests.web.browser import (  # noqa: E402
    find_browser,
    start_chromium,
    unavailable_reason,
    wait_for_state,
)

SAMPLE = REPO / "samples" / "donut.ply"
PAGE_TIMEOUT = 1800


def _open(browser, server: ViewerServer, size: str, query: str, done) -> dict:
    """Navigate afresh to the page with ``query`` and wait until ``done(state)``."""
    browser.get("about:blank")
    server.reset_counter()
    browser.get(f"{server.url}?size={size}{query}")
    state = wait_for_state(browser, lambda s: s["error"] or done(s), timeout=PAGE_TIMEOUT)
    if state["error"]:
        raise RuntimeError(f"the page failed: {state['error']}")
    state["scene_bytes_sent"] = server.scene_bytes_sent
    return state


def streamed_round(browser, path: Path, rate: float, size: str, budget: int | None) -> dict:
    """One round of the streamed file: default view, then every level-0 tile."""
    extra = "" if budget is None else f"&budget={budget}"
    with ViewerServer(path, layers=("color",), rate=rate) as server:
        view = _open(browser, server, size, extra, lambda s: s["lod"] and s["lod"]["complete"])
        full = _open(browser, server, size, extra + "&lodpx=0.001",
                     lambda s: s["lod"] and s["lod"]["complete"])
    lod = view["lod"]
    return {"first_frame_ms": view["firstFrameMs"], "first_frame_bytes": lod["firstFrameBytes"],
            "complete_ms": lod["completeMs"], "complete_bytes": lod["bytesRead"],
            "drawn_levels": lod["drawnLevels"], "drawn_gaussians": view["count"],
            "all_detail_ms": full["lod"]["completeMs"],
            "all_detail_bytes": full["lod"]["bytesRead"],
            "all_detail_gaussians": full["count"],
            "index_read_ms": view["timeline"].get("indexRead"),
            "coarsest_decoded_ms": view["timeline"].get("coarsestDecoded")}


def whole_round(browser, path: Path, rate: float, size: str) -> dict:
    """One round of the whole file, color layer (as the streamed page reads)."""
    with ViewerServer(path, layers=("color",), rate=rate) as server:
        state = _open(browser, server, size, "",
                      lambda s: s["phase"] == "done" and s["colorShown"])
    return {"first_frame_ms": state["firstFrameMs"], "color_frame_ms": state["colorFrameMs"],
            "bytes": state["scene_bytes_sent"], "gaussians": state["count"]}


def _median(rows: list[dict], key: str):
    values = [r[key] for r in rows if r.get(key) is not None]
    return statistics.median(values) if values else None


def measure(levels_file: Path, whole_file: Path, mbit: float, rounds: int, size: str,
            budget: int | None, browser) -> dict:
    """The row of one pair of files."""
    rate = mbit * 1e6 / 8
    streamed, whole = [], []
    for _ in range(rounds):  # interleaved: the two pages see the same machine load
        streamed.append(streamed_round(browser, levels_file, rate, size, budget))
        whole.append(whole_round(browser, whole_file, rate, size))
    size_levels = levels_file.stat().st_size
    first_ms, all_ms = _median(streamed, "first_frame_ms"), _median(streamed, "all_detail_ms")
    whole_ms = _median(whole, "color_frame_ms")
    first_bytes = _median(streamed, "first_frame_bytes")
    return {
        "levels_file": str(levels_file), "whole_file": str(whole_file),
        "levels_file_bytes": size_levels, "whole_file_bytes": whole_file.stat().st_size,
        "link_mbit_s": mbit, "canvas": size, "budget": budget, "rounds": rounds,
        "streamed": streamed, "whole": whole,
        "first_frame_ms_median": first_ms, "first_frame_bytes_median": first_bytes,
        "first_frame_share_of_file": first_bytes / size_levels,
        "complete_ms_median": _median(streamed, "complete_ms"),
        "all_detail_ms_median": all_ms, "whole_color_frame_ms_median": whole_ms,
        "all_detail_over_whole": all_ms / whole_ms,
        "whole_first_frame_ms_median": _median(whole, "first_frame_ms"),
    }


def encode_pair(scene_name: str, levels: int, tile_size: int | None, folder: Path
                ) -> tuple[Path, Path, dict]:
    """Encode a scene with levels and by default; returns the two paths and the encode
    facts."""
    path = SAMPLE if scene_name == "donut" else SCENES / f"{scene_name}.ply"
    scene = read_ply(path)
    facts = {"scene": scene_name, "gaussians": len(scene)}
    start = time.perf_counter()
    leveled = Encoder(levels=levels, tile_size=tile_size).encode(scene)
    facts["levels_encode_s"] = time.perf_counter() - start
    start = time.perf_counter()
    whole = Encoder().encode(scene)
    facts["whole_encode_s"] = time.perf_counter() - start
    (folder / "levels.csgs").write_bytes(leveled)
    (folder / "whole.csgs").write_bytes(whole)
    return folder / "levels.csgs", folder / "whole.csgs", facts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels-file", type=Path)
    parser.add_argument("--whole-file", type=Path)
    parser.add_argument("--scene", help="encode this scene (donut or a shared scene) instead")
    parser.add_argument("--levels", type=int, default=3)
    parser.add_argument("--tile-size", type=int, default=None)
    parser.add_argument("--mbit", type=float, default=50.0, help="simulated link, Mbit/s")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--size", default="800x600", help="canvas WxH in pixels")
    parser.add_argument("--budget", type=int, default=None, help="the page's splat budget")
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    if (args.scene is None) == (args.levels_file is None or args.whole_file is None):
        parser.error("give --scene, or both --levels-file and --whole-file")
    reason = unavailable_reason()
    if reason:
        print(f"cannot run the browser: {reason}", file=sys.stderr)
        return 2
    chromium = subprocess.run([find_browser()[0], "--version"], capture_output=True, text=True,
                              check=False).stdout.strip()
    browser = start_chromium()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            facts = {}
            levels_file, whole_file = args.levels_file, args.whole_file
            if args.scene:
                levels_file, whole_file, facts = encode_pair(args.scene, args.levels,
                                                             args.tile_size, Path(tmp))
            row = {**facts, **measure(levels_file, whole_file, args.mbit, args.rounds,
                                      args.size, args.budget, browser)}
    finally:
        browser.quit()
    print(f"first frame {row['first_frame_ms_median']:.0f} ms from "
          f"{100 * row['first_frame_share_of_file']:.1f}% of the file; all detail "
          f"{row['all_detail_ms_median']:.0f} ms vs whole file "
          f"{row['whole_color_frame_ms_median']:.0f} ms", file=sys.stderr)
    commit = subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"],
                            capture_output=True, text=True, check=False).stdout.strip()
    emit(document("web_levels", [row], browser=chromium, renderer="PlayCanvas 2.23.3",
                  gl="SwiftShader (software WebGL 2, CPU)", commit=commit), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
