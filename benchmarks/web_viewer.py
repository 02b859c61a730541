"""The browser viewer (csgs view --web) in headless Chromium: time to the first frame and to
the first frame with the whole color layer, what share of it the decode takes, and the scene
bytes the page fetches with ``--layers color`` against the whole file.

    .venv/bin/python benchmarks/web_viewer.py [--quality 5] [--rounds 3] [--size 800x600]
        [--scenes donut,playbot,objects] [--baseline REF] [--lanes N] [--out FILE]
        [--anchor-files trained.csgs,...]

Scenes: ``donut`` (samples/donut.ply, the sample), ``playbot`` (../shared/data/scenes, 248k
Gaussians, SH degree 2) and ``objects`` (a synthetic labelled scene, 5 objects x 4,000
Gaussians with 6 semantic channels: the shared scenes carry no semantic layer, so only it
shows what ``--layers color`` leaves out). Each is encoded once with the quality's default
settings (what `csgs encode` writes), served by csgs_codec.web.server and opened ``rounds``
times in a fresh page (Debian chromium, software WebGL through SwiftShader, the machine's CPU
only); the first round of each scene starts with an empty HTTP cache (a new server port).

Per round: ``first_frame_ms`` (navigation start to the first frame drawn with every splat
sorted: page and engine load, header/TOC and color-layer download, decode, upload, sort; the
splats' base color where SH bands are still decoding), ``color_frame_ms`` (the first frame
with the whole color layer), ``color_decode_ms`` (the decode of base + color layers until
the first frame's data) and the page's timeline (when its decode worker started, read the
TOC and the color layer, started and ended decoding; when the renderer was ready).

``--anchor-files``: also open these anchor files (what ``csgs train`` writes); their
``first_frame_ms`` is the frame of the page's preview bake (4 view origins, base color) and
``color_frame_ms`` that of the reference bake (every stored origin, SH degree 3).

``--baseline REF``: also open, in the same run, the page as it was at git commit REF (its
web/, js/ and entropy/data/ folders, served by today's server) on the same scenes encoded
with ``--no-hyperprior`` (the files that page could open), and today's page on those files,
for a same-run ratio.
"""

from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_common import FULL_PRECISION, REPO, SCENES, document, emit  # noqa: E402

from csgs_codec import Decoder, Encoder, read_ply  # noqa: E402
from csgs_codec.format.source import open_source  # noqa: E402
from csgs_codec.format.toc import read_toc  # noqa: E402
from csgs_codec.web.server import PACKAGE_ROOT, ViewerServer  # noqa: E402
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


def open_page(browser, server: ViewerServer, size: str, want_semantic: bool,
              query: str = "") -> dict:
    """Load the page in a fresh navigation and wait until it is done; returns its state."""
    browser.get("about:blank")
    server.reset_counter()
    browser.get(f"{server.url}?size={size}{query}")
    state = wait_for_state(browser, lambda s: s["phase"] in ("done", "error") and (
        s["colorShown"] or s["error"]), timeout=600)
    if state["error"]:
        raise RuntimeError(f"the page failed: {state['error']}")
    if want_semantic and state.get("hasSemantic") and not state["semanticReady"]:
        raise RuntimeError("the semantic layer was not read")
    state["scene_bytes_sent"] = server.scene_bytes_sent
    return state


def baseline_package(ref: str, folder: Path) -> Path:
    """The page, receiver and tables of git commit ``ref``, extracted under ``folder``."""
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", "--format=tar", ref, "csgs_codec/web",
         "csgs_codec/js", "csgs_codec/entropy/data"], capture_output=True, check=True).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    return folder / "csgs_codec"


def _median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def measure_file(name: str, source: str, encode: str, path: Path, page: str,
                 package_root: Path, rounds: int, size: str, browser, gaussians: int,
                 sh_degree: int, encode_s: float, lanes: int | None = None) -> dict:
    """One row: open ``path`` ``rounds`` times with the page under ``package_root`` (today's
    page: on ``lanes`` decode workers, default its own choice)."""
    data = path.read_bytes()
    query = "" if lanes is None else f"&lanes={lanes}"
    rows = []
    with ViewerServer(path, package_root=package_root) as server:
        for _ in range(rounds):
            rows.append(open_page(browser, server, size, want_semantic=True, query=query))
    with ViewerServer(path, layers=("color",), package_root=package_root) as server:
        color_only = open_page(browser, server, size, want_semantic=False, query=query)
    if any(r["count"] != gaussians for r in [*rows, color_only]):
        raise RuntimeError("the page decoded another number of Gaussians than Python")
    first = [r["firstFrameMs"] for r in rows]
    # A page without staged drawing shows the whole color layer in its first frame.
    complete = [r.get("colorFrameMs") or r["firstFrameMs"] for r in rows]
    decode = [r["colorDecodeMs"] for r in rows]
    timeline = {key: _median([r.get("timeline", {}).get(key) for r in rows])
                for key in ("workerStarted", "tocRead", "colorBytesRead", "decodeStarted",
                            "anchorsDecoded", "colorDecoded", "rendererReady")}
    semantic = [r["semanticMs"] for r in rows if r["semanticMs"] is not None]
    return {
        "scene": name, "source": source, "full_precision_scene": name in FULL_PRECISION,
        "encode": encode, "page": page, "decode_lanes": lanes,
        "gaussians": gaussians, "sh_degree": sh_degree,
        "has_semantic_layer": bool(rows[0].get("hasSemantic")), "encode_s": encode_s,
        "canvas": size, "rounds": rounds,
        "first_frame_ms": first, "first_frame_ms_cold": first[0],
        "first_frame_ms_best": min(first), "first_frame_ms_median": statistics.median(first),
        "color_frame_ms": complete, "color_frame_ms_median": statistics.median(complete),
        "color_decode_ms": decode, "color_decode_ms_median": statistics.median(decode),
        "decode_share_of_first_frame": statistics.median(decode) / statistics.median(first),
        "timeline_ms_median": timeline,
        "semantic_ready_ms": semantic or None,
        "file_bytes": len(data), "color_layer_end_bytes": color_end(data),
        "fetched_bytes_color": color_only["scene_bytes_sent"],
        "fetched_bytes_color_semantic": rows[-1]["scene_bytes_sent"],
        "fetched_ratio_color_to_file": color_only["scene_bytes_sent"] / len(data),
    }


def measure(name: str, quality: int, rounds: int, size: str, browser, tmp: Path,
            baseline: tuple[str, Path] | None, lanes: int | None) -> list[dict]:
    """The rows of one scene: today's page on the default encode; with a baseline, both
    pages on the ``--no-hyperprior`` encode."""
    scene, source = load_scene(name)
    out = []
    variants = [("default", {})] + ([("no-hyperprior", {"hyperprior": False})] if baseline else [])
    for encode, options in variants:
        start = time.perf_counter()
        data = Encoder(quality=quality, **options).encode(scene)
        encode_s = time.perf_counter() - start
        decoded = Decoder().decode(data, layers="color")
        path = tmp / f"{name}_{encode}.csgs"
        path.write_bytes(data)
        pages = [("current", PACKAGE_ROOT)]
        if baseline and encode == "no-hyperprior":
            pages.append((f"baseline {baseline[0]}", baseline[1]))
        for page, root in pages:
            out.append(measure_file(name, source, f"quality {quality}, {encode}", path, page,
                                    root, rounds, size, browser, len(decoded),
                                    decoded.sh_degree_stored, encode_s,
                                    lanes if page == "current" else None))
            row = out[-1]
            print(f"{name} [{encode}, {page}]: first frame {row['first_frame_ms']} ms, "
                  f"color {row['color_frame_ms']} ms", file=sys.stderr)
    return out


def measure_anchor_file(path: Path, rounds: int, size: str, browser) -> dict:
    """The row of a trained anchor file (what ``csgs train`` writes): the page decodes the
    anchors, draws a preview bake, then the reference bake (as many splats as Python's)."""
    from csgs_codec.bake.anchor_bake import bake_anchor_scene
    from csgs_codec.codec.anchor_decoder import AnchorDecoder

    anchors = AnchorDecoder().decode(path)
    baked = bake_anchor_scene(anchors)
    row = measure_file(path.stem, str(path), "csgs train (anchor scene)", path, "current",
                       PACKAGE_ROOT, rounds, size, browser, len(baked),
                       baked.sh_degree_stored, None)
    row.update({"anchors": len(anchors), "anchor_slots": anchors.active_offsets()})
    print(f"{path.name} [anchors]: first frame {row['first_frame_ms']} ms, "
          f"baked {row['color_frame_ms']} ms", file=sys.stderr)
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default="donut,playbot,objects")
    parser.add_argument("--quality", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--size", default="800x600", help="canvas WxH in pixels")
    parser.add_argument("--baseline", metavar="REF",
                        help="also time the page of this git commit, same run")
    parser.add_argument("--lanes", type=int, default=None,
                        help="today's page decodes on this many Web Workers (default: its own "
                             "choice, one per core but one, up to 4; 0: in its decode "
                             "worker)")
    parser.add_argument("--anchor-files", default="",
                        help="comma-separated anchor .csgs files (csgs train output) to open "
                             "too")
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
            baseline = None
            if args.baseline:
                baseline = (args.baseline, baseline_package(args.baseline, Path(tmp) / "base"))
            for name in filter(None, args.scenes.split(",")):
                results += measure(name.strip(), args.quality, args.rounds, args.size, browser,
                                   Path(tmp), baseline, args.lanes)
            for name in filter(None, args.anchor_files.split(",")):
                results.append(measure_anchor_file(Path(name.strip()), args.rounds,
                                                   args.size, browser))
    finally:
        browser.quit()
    commit = subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"],
                            capture_output=True, text=True, check=False).stdout.strip()
    emit(document("web_viewer", results, browser=chromium, renderer="PlayCanvas 2.23.3",
                  gl="SwiftShader (software WebGL 2, CPU)", commit=commit), args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
