"""The browser viewer (csgs view --web) in headless Chromium: time to first frame and the scene
bytes the page fetches with ``--layers color`` against the whole file.

    .venv/bin/python benchmarks/web_viewer.py [--quality 5] [--rounds 3] [--size 800x600]
        [--scenes donut,playbot,objects] [--out FILE]

Scenes: ``donut`` (samples/donut.ply, the sample), ``playbot`` (../shared/data/scenes, 248k
Gaussians, SH degree 2) and ``objects`` (a synthetic labelled scene, 5 objects x 4,000
Gaussians with 6 semantic channels: the shared scenes carry no semantic layer, so only it
shows what ``--layers color`` leaves out). Each is encoded once with the quality's default
settings, served by csgs_codec.web.server and opened ``rounds`` times in a fresh page
(Debian chromium, software WebGL through SwiftShader, the machine's CPU only). Per round:
``first_frame_ms`` (from navigation start to the first frame drawn with the splats sorted:
page and engine load, header/TOC and color-layer download, worker decode, upload, sort),
``color_decode_ms`` (the worker's decode of base + color layers) and, with both layers,
``semantic_ready_ms``. Bytes: what the server sent of the scene file for a page asked for
``color`` and for ``color,semantic``, against the file size.
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

from bench_common import FULL_PRECISION, REPO, SCENES, document, emit  # noqa: E402

from csgs_codec import Decoder, Encoder, read_ply  # noqa: E402
from csgs_codec.format.source import open_source  # noqa: E402
from csgs_codec.format.toc import read_toc  # noqa: E402
from csgs_codec.web.server import ViewerServer  # noqa: E402
from tests.web.browser import (  # noqa: E402
    find_browser,
    start_chromium,
    unavailable_reason,
    wait_for_state,
)

SAMPLE = REPO / "samples" / "donut.ply"


def load_scene(name: str):
    """(GaussianScene, source description) of a benchmark scene name."""
    if name == "donut":
        return read_ply(SAMPLE), "samples/donut.ply"
    if name == "objects":
        from csgs_codec.semantic.synthetic import labelled_blob_scene

        return labelled_blob_scene(5, 4000, seed=3), "labelled_blob_scene(5, 4000, seed=3)"
    path = SCENES / f"{name}.ply"
    if not path.exists():
        raise FileNotFoundError(f"shared scene not present: {path}")
    return read_ply(path), f"../shared/data/scenes/{path.name}"


def color_end(data: bytes) -> int:
    """Bytes from the start of the file to the end of its color layer."""
    toc = read_toc(open_source(data))
    return max(entry.end for entry in toc.entries if int(entry.layer) <= 1)


def open_page(browser, server: ViewerServer, size: str, want_semantic: bool) -> dict:
    """Load the page in a fresh navigation and wait until it is done; returns its state."""
    browser.get("about:blank")
    server.reset_counter()
    browser.get(f"{server.url}?size={size}")
    state = wait_for_state(browser, lambda s: s["phase"] in ("done", "error") and (
        s["colorShown"] or s["error"]), timeout=600)
    if state["error"]:
        raise RuntimeError(f"the page failed: {state['error']}")
    if want_semantic and state.get("hasSemantic") and not state["semanticReady"]:
        raise RuntimeError("the semantic layer was not read")
    state["scene_bytes_sent"] = server.scene_bytes_sent
    return state


def measure(name: str, quality: int, rounds: int, size: str, browser, tmp: Path) -> dict:
    """One row: encode, then time the page ``rounds`` times and count the bytes it fetches."""
    scene, source = load_scene(name)
    start = time.perf_counter()
    data = Encoder(quality=quality).encode(scene)
    encode_s = time.perf_counter() - start
    decoded = Decoder().decode(data, layers="color")
    path = tmp / f"{name}.csgs"
    path.write_bytes(data)
    rows = []
    with ViewerServer(path) as server:
        for _ in range(rounds):
            rows.append(open_page(browser, server, size, want_semantic=True))
    with ViewerServer(path, layers=("color",)) as server:
        color_only = open_page(browser, server, size, want_semantic=False)
    if any(r["count"] != len(decoded) for r in [*rows, color_only]):
        raise RuntimeError("the page decoded another number of Gaussians than Python")
    first = [r["firstFrameMs"] for r in rows]
    decode = [r["colorDecodeMs"] for r in rows]
    semantic = [r["semanticMs"] for r in rows if r["semanticMs"] is not None]
    return {
        "scene": name, "source": source, "full_precision_scene": name in FULL_PRECISION,
        "quality": quality, "gaussians": len(decoded), "sh_degree": decoded.sh_degree_stored,
        "has_semantic_layer": bool(rows[0].get("hasSemantic")), "encode_s": encode_s,
        "canvas": size, "rounds": rounds,
        "first_frame_ms": first, "first_frame_ms_best": min(first),
        "first_frame_ms_median": statistics.median(first),
        "color_decode_ms": decode, "color_decode_ms_median": statistics.median(decode),
        "semantic_ready_ms": semantic or None,
        "file_bytes": len(data), "color_layer_end_bytes": color_end(data),
        "fetched_bytes_color": color_only["scene_bytes_sent"],
        "fetched_bytes_color_semantic": rows[-1]["scene_bytes_sent"],
        "fetched_ratio_color_to_file": color_only["scene_bytes_sent"] / len(data),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default="donut,playbot,objects")
    parser.add_argument("--quality", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--size", default="800x600", help="canvas WxH in pixels")
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    reason = unavailable_reason()
    if reason:
        print(f"cannot run the browser: {reason}", file=sys.stderr)
        return 2
    chromium = subprocess.run([find_browser()[0], "--version"], capture_output=True, text=True,
                              check=False).stdout.strip()
    results = []
    browser = start_chromium()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for name in args.scenes.split(","):
                results.append(measure(name.strip(), args.quality, args.rounds, args.size,
                                       browser, Path(tmp)))
                print(f"{name}: first frame {results[-1]['first_frame_ms']} ms", file=sys.stderr)
    finally:
        browser.quit()
    emit(document("web_viewer", results, browser=chromium, renderer="PlayCanvas 2.23.3",
                  gl="SwiftShader (software WebGL 2, CPU)"), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
