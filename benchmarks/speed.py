"""Speed benchmark: encode and decode wall time, peak memory and size against scene size.

For each scene, size and quality preset: a scene of that many Gaussians (a seeded subset of
the real scene below its size, the whole scene plus jittered copies above it; see
benchmarks/_scaling.py) is encoded and decoded (color layer), each phase in a fresh process
(benchmarks/_speed_worker.py) that times it, records its peak resident-memory growth and
tracemalloc's peak of the numpy side, and checks the decode equals the encoder's
reconstruction bit for bit. A power law time ~ N^b is fitted per scene, preset, phase and
metric (least squares on log-log), over all sizes and over the large sizes alone (where fixed
per-call costs no longer flatter it). Targets: b <= 1.1; color-layer decode >= 300k
Gaussians/s on 2 cores.

    .venv/bin/python benchmarks/speed.py --out bench-output/speed.json \\
        --plot bench-output/speed.png
    .venv/bin/python benchmarks/speed.py --quick          # small sizes, one preset, one run

The workers import csgs_codec the way this process does, so PYTHONPATH=DIR measures the codec
in DIR (e.g. a ``git archive`` of one commit) while the working tree keeps changing; the
document's ``codec_path`` says which was measured.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _fit import growth_exponent  # noqa: E402
from _png_plot import Chart, Series, color, save_charts  # noqa: E402
from _scaling import JITTER_FRACTION, save_arrays, scene_of_size  # noqa: E402
from bench_common import FULL_PRECISION, SCENES, document, emit  # noqa: E402

import csgs_codec  # noqa: E402
from csgs_codec import read_ply  # noqa: E402

DEFAULT_SIZES = (10_000, 30_000, 100_000, 250_000, 500_000, 1_000_000, 2_000_000)
QUICK_SIZES = (10_000, 20_000, 40_000)
DEFAULT_QUALITIES = (2, 5, 8)
QUICK_QUALITIES = (5,)
#: Fits "over the large sizes" use N >= this.
LARGE_FROM = 250_000
TARGET_EXPONENT = 1.1
TARGET_DECODE_GAUSSIANS_PER_S = 300_000
WORKER = Path(__file__).resolve().with_name("_speed_worker.py")
PHASES = ("encode", "decode")
#: Row keys fitted against N, per phase: (key suffix, name in the growth table).
METRICS = (("s", "seconds"), ("cpu_s", "cpu_seconds"),
           ("peak_rss_delta_mb", "peak_rss_delta_mb"), ("numpy_peak_mb", "numpy_peak_mb"))
MB = 1024 * 1024


def run_phase(phase: str, folder: Path, quality: int, budget_s: float, max_runs: int,
              timeout_s: float) -> dict:
    """Run one phase in a fresh interpreter and return its JSON report."""
    command = [sys.executable, str(WORKER), phase, str(folder), str(quality), str(budget_s),
               str(max_runs)]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s,
                              cwd=WORKER.parent)
    except subprocess.TimeoutExpired:
        raise SystemExit(f"{phase} of {folder.name} q{quality} ran past {timeout_s} s") from None
    if done.returncode != 0:
        raise SystemExit(f"{phase} worker failed for {folder.name} q{quality}:\n"
                         f"{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def point_row(scene_name: str, source_count: int, construction: str, quality: int,
              sh_degree: int, encoded: dict, decoded: dict) -> dict:
    """One result row from the two phase reports of a (scene, size, preset) point."""
    n = encoded["gaussians"]
    if not decoded["roundtrip_ok"] or decoded["gaussians"] != n:
        raise SystemExit(f"{scene_name} N={n} q{quality}: decode differs from the encoder's "
                         "reconstruction")
    row = {"scene": scene_name, "full_precision_scene": scene_name in FULL_PRECISION,
           "source_gaussians": source_count, "construction": construction,
           "gaussians": n, "sh_degree": sh_degree, "quality": quality,
           "bytes": encoded["bytes"], "bits_per_gaussian": 8 * encoded["bytes"] / n}
    for phase, report in (("encode", encoded), ("decode", decoded)):
        best = min(report["seconds"])
        row[f"{phase}_s"] = best
        row[f"{phase}_runs_s"] = report["seconds"]
        row[f"{phase}_gaussians_per_s"] = n / best
        row[f"{phase}_cpu_s"] = min(report["cpu_seconds"])
        row[f"{phase}_gaussians_per_cpu_s"] = n / row[f"{phase}_cpu_s"]
        row[f"{phase}_peak_rss_delta_mb"] = report["peak_rss_delta_bytes"] / MB
        row[f"{phase}_numpy_peak_mb"] = report["tracemalloc_peak_bytes"] / MB
        row[f"{phase}_rss_peak_was_reset"] = report["peak_was_reset"]
    row["roundtrip_ok"] = True
    return row


def growth_rows(rows: list[dict], large_from: int) -> list[dict]:
    """Fitted exponents per scene, preset, phase and metric, over all and large sizes."""
    out = []
    for scene, quality in sorted({(r["scene"], r["quality"]) for r in rows}):
        series = sorted((r for r in rows if r["scene"] == scene and r["quality"] == quality),
                        key=lambda r: r["gaussians"])
        for phase in PHASES:
            for suffix, metric in METRICS:
                for label, picked in (("all", series),
                                      (f">= {large_from}",
                                       [r for r in series if r["gaussians"] >= large_from])):
                    sizes = [r["gaussians"] for r in picked]
                    exponent = growth_exponent(sizes, [r[f"{phase}_{suffix}"] for r in picked])
                    out.append({"scene": scene, "quality": quality, "phase": phase,
                                "metric": metric, "sizes": label, "points": len(sizes),
                                "exponent": exponent})
    return out


def summary_rows(rows: list[dict], growth: list[dict], large_from: int) -> list[dict]:
    """Per scene and preset: the figures the targets are judged on, and the verdicts."""
    out = []
    for scene, quality in sorted({(r["scene"], r["quality"]) for r in rows}):
        series = sorted((r for r in rows if r["scene"] == scene and r["quality"] == quality),
                        key=lambda r: r["gaussians"])
        largest = series[-1]

        def exponent(phase, sizes, metric="seconds", scene=scene, quality=quality):
            return next(g["exponent"] for g in growth
                        if (g["scene"], g["quality"], g["phase"], g["metric"], g["sizes"])
                        == (scene, quality, phase, metric, sizes))

        large = f">= {large_from}"
        judged = large if exponent("encode", large) is not None else "all"
        row = {"scene": scene, "quality": quality, "largest_gaussians": largest["gaussians"],
               "exponents_judged_on_sizes": judged}
        for phase in PHASES:
            row[f"{phase}_time_exponent"] = exponent(phase, judged)
            row[f"{phase}_time_exponent_all_sizes"] = exponent(phase, "all")
            row[f"{phase}_cpu_time_exponent"] = exponent(phase, judged, "cpu_seconds")
            row[f"{phase}_memory_exponent"] = exponent(phase, judged, "peak_rss_delta_mb")
            row[f"{phase}_numpy_memory_exponent"] = exponent(phase, judged, "numpy_peak_mb")
            row[f"{phase}_gaussians_per_s_at_largest"] = largest[f"{phase}_gaussians_per_s"]
            row[f"{phase}_gaussians_per_cpu_s_at_largest"] = \
                largest[f"{phase}_gaussians_per_cpu_s"]
        rates = [r["decode_gaussians_per_s"] for r in series if r["gaussians"] >= large_from]
        row["decode_gaussians_per_s_min_large"] = min(rates) if rates else None
        for kind, key in (("", "time_exponent"), ("_cpu", "cpu_time_exponent")):
            row[f"meets_exponent_target{kind}"] = all(
                row[f"{p}_{key}"] is not None and row[f"{p}_{key}"] <= TARGET_EXPONENT
                for p in PHASES)
        row["meets_decode_rate_target"] = (row["decode_gaussians_per_s_at_largest"]
                                           >= TARGET_DECODE_GAUSSIANS_PER_S)
        out.append(row)
    return out


def plot(rows: list[dict], growth: list[dict], large_from: int, path: str) -> None:
    """Wall and CPU time of each phase, decode rate and peak memory against N, one PNG.

    Time panels are log-log with the fitted power law drawn over the sizes it was fitted on
    (the large sizes where there are enough, else all).
    """
    keys = sorted({(r["scene"], r["quality"]) for r in rows})
    timed = [(phase, key, metric) for phase in PHASES
             for key, metric in ((f"{phase}_s", "seconds"), (f"{phase}_cpu_s", "cpu_seconds"))]
    charts = [Chart(f"{phase} {'wall' if metric == 'seconds' else 'CPU'} time"
                    + (" (color layer)" if phase == "decode" else ""), "Gaussians", "seconds",
                    log_x=True, log_y=True) for phase, _, metric in timed]
    rate = Chart("decode rate (color layer)", "Gaussians", "Gaussians / s", log_x=True)
    memory = Chart("peak resident memory growth", "Gaussians", "MiB", log_x=True, log_y=True)
    for i, (scene, quality) in enumerate(keys):
        series = sorted((r for r in rows if r["scene"] == scene and r["quality"] == quality),
                        key=lambda r: r["gaussians"])
        name = f"{scene} q{quality}" if len({k[0] for k in keys}) > 1 else f"q{quality}"
        for chart, (phase, key, metric) in zip(charts, timed):
            ns = [r["gaussians"] for r in series]
            chart.add(Series(name, ns, [r[key] for r in series], color(i)))
            fitted = [r for r in series if r["gaussians"] >= large_from]
            fitted, sizes = (fitted, f">= {large_from}") if len(fitted) >= 2 else (series, "all")
            exponent = next(g["exponent"] for g in growth
                            if (g["scene"], g["quality"], g["phase"], g["metric"], g["sizes"])
                            == (scene, quality, phase, metric, sizes))
            if exponent is not None:
                fns = [r["gaussians"] for r in fitted]
                chart.add(Series(f"N^{exponent:.2f} ({sizes})", [fns[0], fns[-1]],
                                 _power_fit(fns, [r[key] for r in fitted], exponent),
                                 color(i), marker=None, line=True, dashed=True))
        ns = [r["gaussians"] for r in series]
        rate.add(Series(f"{name} wall", ns, [r["decode_gaussians_per_s"] for r in series],
                        color(i), line=True))
        rate.add(Series(f"{name} CPU", ns, [r["decode_gaussians_per_cpu_s"] for r in series],
                        color(i), marker="square", line=True, dashed=True))
        for phase, dashed, marker in (("encode", False, "circle"), ("decode", True, "square")):
            memory.add(Series(f"{name} {phase}", ns,
                              [r[f"{phase}_peak_rss_delta_mb"] for r in series], color(i),
                              marker=marker, line=True, dashed=dashed))
    all_ns = [r["gaussians"] for r in rows]
    rate.add(Series("target 300k/s", [min(all_ns), max(all_ns)],
                    [TARGET_DECODE_GAUSSIANS_PER_S] * 2, (0, 0, 0), marker=None, line=True,
                    dashed=True))
    save_charts([*charts, rate, memory], path, columns=2)


def _power_fit(ns: list[int], values: list[float], exponent: float) -> list[float]:
    """Endpoints of value = a * N^exponent through the geometric mean of the points."""
    log_a = sum(math.log(v) - exponent * math.log(n) for n, v in zip(ns, values)) / len(ns)
    return [math.exp(log_a + exponent * math.log(n)) for n in (ns[0], ns[-1])]


def report(rows: list[dict], args, wall_s: float, complete: bool) -> None:
    """Fit, then write the document (and plot); ``complete`` False marks a checkpoint
    written after each point, so a run stopped early keeps what it measured."""
    growth = growth_rows(rows, args.large_from)
    summary = summary_rows(rows, growth, args.large_from)
    for target in (args.out, args.plot):
        if target:
            Path(target).parent.mkdir(parents=True, exist_ok=True)
    emit(document("speed", rows, quick=args.quick, complete=complete,
                  codec_path=str(Path(csgs_codec.__file__).parent), seed=args.seed,
                  jitter_fraction=JITTER_FRACTION, large_from=args.large_from,
                  targets={"time_exponent_max": TARGET_EXPONENT,
                           "decode_gaussians_per_s_min": TARGET_DECODE_GAUSSIANS_PER_S},
                  wall_s=wall_s, growth=growth, summary=summary), args.out)
    if args.plot:
        plot(rows, growth, args.large_from, args.plot)


def main() -> int:
    """Run the benchmark; see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="*", default=["playbot"],
                        help="scene names (PLY stems) in --scenes-dir (default: playbot)")
    parser.add_argument("--scenes-dir", default=str(SCENES))
    parser.add_argument("--sizes", nargs="*", type=int, default=None,
                        help=f"Gaussian counts (default: {' '.join(map(str, DEFAULT_SIZES))})")
    parser.add_argument("--qualities", nargs="*", type=int, default=None,
                        help="presets (default: 2 5 8; with --quick: 5)")
    parser.add_argument("--quick", action="store_true",
                        help="small sizes, one preset, one timed run per phase (smoke test)")
    parser.add_argument("--budget", type=float, default=None,
                        help="repeat a phase while its runs total under this many seconds "
                             "(default 3; 0 with --quick); the best run is reported")
    parser.add_argument("--max-runs", type=int, default=5)
    parser.add_argument("--large-from", type=int, default=LARGE_FROM)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=1800, help="seconds per phase")
    parser.add_argument("--out", default=None, help="JSON file (default: stdout)")
    parser.add_argument("--plot", default=None, help="PNG of time and memory against N")
    args = parser.parse_args()
    sizes = args.sizes or list(QUICK_SIZES if args.quick else DEFAULT_SIZES)
    qualities = args.qualities or list(QUICK_QUALITIES if args.quick else DEFAULT_QUALITIES)
    budget = args.budget if args.budget is not None else (0.0 if args.quick else 3.0)

    rows: list[dict] = []
    started = time.perf_counter()
    for name in args.scenes:
        source = read_ply(Path(args.scenes_dir) / f"{name}.ply")
        sh_degree = source.sh_degree_in_use()
        for n in sorted(sizes):
            with tempfile.TemporaryDirectory(prefix="csgs-speed-") as tmp:
                folder = Path(tmp)
                scene, construction = scene_of_size(source, n, args.seed)
                save_arrays(scene, folder / "scene")
                del scene
                for q in qualities:
                    encoded = run_phase("encode", folder, q, budget, args.max_runs, args.timeout)
                    decoded = run_phase("decode", folder, q, budget, args.max_runs, args.timeout)
                    rows.append(point_row(name, len(source), construction, q, sh_degree,
                                          encoded, decoded))
                    if args.out:
                        report(rows, args, time.perf_counter() - started, complete=False)
                    r = rows[-1]
                    print(f"{name} N={n} q{q}: encode {r['encode_s']:.2f} s "
                          f"(CPU {r['encode_cpu_s']:.2f}), decode {r['decode_s']:.2f} s "
                          f"(CPU {r['decode_cpu_s']:.2f}), {r['bits_per_gaussian']:.1f} bits/G",
                          file=sys.stderr)
    report(rows, args, time.perf_counter() - started, complete=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
