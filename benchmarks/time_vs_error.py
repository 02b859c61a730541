"""Time against error: encode time, decode time, render PSNR and size, with the Pareto fronts.

For each scene and csgs quality preset: encode, decode (color layer), check the decode equals
the encoder's reconstruction, then render both from the RD benchmark's orbit views and score
them (the project's own rasterizer, black background, foreground PSNR as the headline). The
peer codecs are not re-run: their rows (size, encode and decode time, PSNR) come from a JSON
document written by benchmarks/rd.py, scored with the same views and image size (taken from
that document), so their render scores are comparable; their times were measured in that run,
on its machine (the document's ``peer_source`` says which). Every row is marked Pareto-optimal
or not, per scene, on foreground PSNR against size, encode time, decode time, and all three
at once: the front a user picks a codec and setting from.

With ``--fast`` every preset also gets a row encoded with ``Encoder(fast=True)`` (setting
"quality N fast", ``"fast": true``; the other csgs rows have ``"fast": false``), its own series
in the plot. Timings are CPU-time-sensitive on a shared machine: run with ``--repeats 3``.

    .venv/bin/python benchmarks/time_vs_error.py --rd bench-output/rd.json \\
        --out bench-output/time_vs_error.json --plot bench-output/time_vs_error.png \\
        --table bench-output/time_vs_error.md [--fast]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _fit import pareto_optimal  # noqa: E402
from _png_plot import MARKERS, Chart, Series, color, save_charts  # noqa: E402
from bench_common import FULL_PRECISION, REPO, SCENES, document, emit  # noqa: E402

from csgs_codec import Decoder, Encoder, read_ply  # noqa: E402

DEFAULT_RD = REPO / "benchmarks" / "results" / "rd_2026-11-23.json"
DEFAULT_QUALITIES = tuple(range(1, 10))
#: Score every front is drawn on (docs/design.md, 'Measuring quality': the headline).
FRONT_METRIC = "foreground_psnr"
#: Front name -> the costs (row keys, minimised) it weighs against the score.
FRONTS = {"pareto_size": ("bytes",), "pareto_encode": ("encode_s",),
          "pareto_decode": ("decode_s",), "pareto": ("bytes", "encode_s", "decode_s")}
PEER_KEYS = ("scene", "codec", "setting", "bytes", "bits_per_gaussian", "encode_s",
             "decode_s", "psnr", "ssim", "foreground_psnr")


def load_rd(path: Path) -> dict:
    """The csgs-bench/1 document benchmarks/rd.py wrote at ``path``."""
    doc = json.loads(Path(path).read_text())
    if doc.get("schema") != "csgs-bench/1" or doc.get("benchmark") != "rd":
        raise SystemExit(f"{path}: not a csgs-bench/1 rd document")
    return doc


def peer_rows(rd: dict, scenes: list[str], rd_path: Path) -> list[dict]:
    """The RD document's peer rows for ``scenes``, reduced to the columns compared here."""
    rows = []
    for row in rd["results"]:
        if row.get("codec") != "csgs" and row.get("scene") in scenes:
            rows.append({**{k: row.get(k) for k in PEER_KEYS}, "quality": None,
                         "measured_in": str(rd_path)})
    return rows


def csgs_rows(name: str, original, references, cameras, qualities, backend: str,
              repeats: int, fast: bool = False) -> list[dict]:
    """Encode, decode, check and score ``original`` at every quality; one row each
    (``fast``: with the fast encoder mode)."""
    from csgs_codec.metrics.comparison import score_view

    rows = []
    for q in qualities:
        encode_s, decode_s = [], []
        for _ in range(repeats):
            start = time.perf_counter()
            result = Encoder(quality=q, fast=fast).encode_with_report(original)
            encode_s.append(time.perf_counter() - start)
            start = time.perf_counter()
            decoded = Decoder().decode(result.data, layers="color")
            decode_s.append(time.perf_counter() - start)
        if not decoded.equals(result.reconstruction):
            raise SystemExit(f"{name} q{q}: decode differs from the encoder's reconstruction")
        views = [score_view(ref, decoded, cam, backend=backend)
                 for ref, cam in zip(references, cameras)]
        rows.append({"scene": name, "codec": "csgs",
                     "setting": f"quality {q}" + (" fast" if fast else ""), "quality": q,
                     "fast": fast,
                     "bytes": len(result.data),
                     "bits_per_gaussian": 8 * len(result.data) / max(1, len(original)),
                     "encode_s": min(encode_s), "decode_s": min(decode_s),
                     "psnr": _mean([v.psnr for v in views]),
                     "ssim": _mean([v.ssim for v in views]),
                     "foreground_psnr": _mean([v.foreground_psnr for v in views]),
                     "measured_in": "this run"})
    return rows


def mark_fronts(rows: list[dict]) -> None:
    """Set each row's pareto_* flags: optimal among its scene's rows for each front."""
    for scene in sorted({r["scene"] for r in rows}):
        mine = [r for r in rows if r["scene"] == scene]
        for front, keys in FRONTS.items():
            costs = np.array([[_cost(r.get(k)) for k in keys] + [-_cost(r.get(FRONT_METRIC))]
                              for r in mine])
            for row, optimal in zip(mine, pareto_optimal(costs)):
                row[front] = bool(optimal)


def table(rows: list[dict]) -> str:
    """A Markdown table of every row: scene, codec, setting, size, times, scores, fronts."""
    head = ("scene", "codec", "setting", "KiB", "bits/G", "encode s", "decode s", "PSNR",
            "fg PSNR", "Pareto (size/enc/dec/all)")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in sorted(rows, key=lambda r: (r["scene"], r["codec"] != "csgs", r["codec"],
                                         r["bytes"])):
        flags = "/".join("*" if r.get(f) else "-" for f in FRONTS)
        cells = (r["scene"], r["codec"], r["setting"] or "", f"{r['bytes'] / 1024:,.1f}",
                 _num(r["bits_per_gaussian"], 1), _num(r["encode_s"], 3),
                 _num(r["decode_s"], 3), _num(r["psnr"], 2), _num(r[FRONT_METRIC], 2), flags)
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot(rows: list[dict], path: str) -> None:
    """Per scene (columns): foreground PSNR against encode time, decode time and bits per
    Gaussian (rows of panels), csgs presets joined, peers as markers, the front in grey and
    its points ringed."""
    scenes = sorted({r["scene"] for r in rows})
    codecs = sorted({_series(r) for r in rows}, key=lambda c: (not c.startswith("csgs"), c))
    axes = (("encode_s", "pareto_encode", "encode wall time (s)", True),
            ("decode_s", "pareto_decode", "decode wall time (s)", True),
            ("bits_per_gaussian", "pareto_size", "bits per Gaussian", True))
    charts = []
    for key, front, label, log_x in axes:
        for scene in scenes:
            mine = [r for r in rows if r["scene"] == scene]
            title = scene + ("" if scene in FULL_PRECISION else " (re-decoded)")
            chart = Chart(title, label, "foreground PSNR (dB)", log_x=log_x)
            best = sorted((r for r in mine if r.get(front) and r.get(key) is not None),
                          key=lambda r: r[key])
            chart.add(Series("Pareto front", [r[key] for r in best],
                             [r[FRONT_METRIC] for r in best], (170, 170, 170), marker=None,
                             line=True))
            for i, codec in enumerate(codecs):
                points = sorted((r for r in mine if _series(r) == codec),
                                key=lambda r: r.get("quality") or 0)
                if points:
                    chart.add(Series(codec, [r[key] for r in points],
                                     [r[FRONT_METRIC] for r in points], color(i),
                                     marker=MARKERS[i % len(MARKERS)],
                                     line=codec.startswith("csgs"),
                                     highlight=[bool(r.get(front)) for r in points]))
            charts.append(chart)
    save_charts(charts, path, columns=len(scenes))


def _series(row: dict) -> str:
    """Plot series of a row: its codec, with " fast" for fast-mode csgs rows."""
    return row["codec"] + (" fast" if row.get("fast") else "")


def _cost(value) -> float:
    return float("nan") if value is None else float(value)


def _mean(values: list[float]) -> float:
    """Mean over views, leaving out NaN (no foreground) and inf (identical) unless all are."""
    finite = [v for v in values if math.isfinite(v)]
    if finite:
        return float(np.mean(finite))
    return float("inf") if values and all(v == math.inf for v in values) else float("nan")


def _num(value, digits: int) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def main() -> int:
    """Run the benchmark; see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rd", default=str(DEFAULT_RD),
                        help="rd.json from benchmarks/rd.py with the peer rows")
    parser.add_argument("--scenes", nargs="*", default=None,
                        help="scene names (default: the RD document's scenes found here)")
    parser.add_argument("--scenes-dir", default=str(SCENES))
    parser.add_argument("--qualities", nargs="*", type=int, default=list(DEFAULT_QUALITIES))
    parser.add_argument("--views", type=int, default=None, help="default: the RD document's")
    parser.add_argument("--size", default=None, help="WxH; default: the RD document's")
    parser.add_argument("--repeats", type=int, default=1,
                        help="encode and decode this many times; the best time is reported")
    parser.add_argument("--fast", action="store_true",
                        help="also encode every preset with the fast encoder mode")
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--out", default=None, help="JSON file (default: stdout)")
    parser.add_argument("--plot", default=None, help="PNG of PSNR against time and size")
    parser.add_argument("--table", default=None, help="Markdown table (also printed to stderr)")
    args = parser.parse_args()

    from csgs_codec.metrics.comparison import render_references
    from csgs_codec.scene.orbit import orbit_cameras

    rd_path = Path(args.rd)
    rd = load_rd(rd_path)
    views = args.views or int(rd.get("views", 16))
    size = args.size or rd.get("size", "800x600")
    comparable = views == rd.get("views") and size == rd.get("size")
    if not comparable:
        print(f"warning: scoring with {views} views at {size}, the peers' scores used "
              f"{rd.get('views')} at {rd.get('size')}", file=sys.stderr)
    width, height = (int(v) for v in size.lower().split("x"))
    scenes_dir = Path(args.scenes_dir)
    names = args.scenes or sorted({r["scene"] for r in rd["results"]
                                   if (scenes_dir / f"{r['scene']}.ply").exists()})

    rows: list[dict] = []
    for name in names:
        original = read_ply(scenes_dir / f"{name}.ply")
        cameras = orbit_cameras(original, views, width=width, height=height)
        references = render_references(original, cameras, backend=args.backend)
        for fast in (False, True) if args.fast else (False,):
            rows += csgs_rows(name, original, references, cameras, args.qualities,
                              args.backend, max(1, args.repeats), fast=fast)
        print(f"{name}: done", file=sys.stderr)
    rows += peer_rows(rd, names, rd_path)
    for row in rows:
        row["full_precision_scene"] = row["scene"] in FULL_PRECISION
    mark_fronts(rows)
    text = table(rows)
    print(text, file=sys.stderr)
    for target in (args.out, args.plot, args.table):
        if target:
            Path(target).parent.mkdir(parents=True, exist_ok=True)
    if args.table:
        Path(args.table).write_text(text)
    emit(document("time_vs_error", rows, views=views, size=size, front_metric=FRONT_METRIC,
                  fronts={k: list(v) for k, v in FRONTS.items()},
                  peer_source={"path": str(rd_path), "machine": rd.get("machine"),
                               "scores_comparable": comparable}), args.out)
    if args.plot:
        plot(rows, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
