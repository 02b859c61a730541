"""Write docs/results.md from the recorded benchmark runs in benchmarks/results/*.json.

For each benchmark kind (a document's ``"benchmark"`` field) the page shows the kind's newest
files. A file's name is a series, a date, and a letter or ``_partN`` for a later run of that
series on that day (``tiles_2026-11-24f.json``); the newest file of each series counts, and
of those, the ones of the kind's newest date are shown (``js_decode_donut_2026-11-27.json``
and ``js_decode_playbot_2026-11-27.json``, say). Each gets the machine it ran on, its scalar
settings and a short table of key figures: a handful of columns chosen per kind below, or,
for a kind not listed, every scalar field its rows have. The kind's other files are named.
The hand-written section ``## Notes measured by hand`` at the end of docs/results.md is kept
as it is: the page is generated above it and copied below it.

Usage::

    python benchmarks/results_md.py            # rewrite docs/results.md
    python benchmarks/results_md.py --check    # exit 1 when docs/results.md is out of date

The output depends on the JSON files and the notes only (sorted, no clock), so ``--check``
can run in a test.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"
OUTPUT = REPO / "docs" / "results.md"
SCHEMA = "csgs-bench/1"
NOTES_HEADING = "## Notes measured by hand"
#: Rows shown per table; the rest are counted and left in the file.
MAX_ROWS = 20
#: A results file's stem: its series, its date, then a letter or _partN for a later run.
DATED = re.compile(
    r"^(?P<series>.*?)_?(?P<date>\d{4}-\d{2}-\d{2})(?P<run>[a-z]?)(?:_part(?P<part>\d+))?$")


class View:
    """One table of a kind: which rows (``where``: field -> required value, ``has``: fields a
    row must have, ``each``: a list field whose items are the rows) and which columns (dotted
    paths into a row)."""

    def __init__(self, columns: list[str], *, title: str = "", where: dict | None = None,
                 exclude: dict | None = None, has: tuple[str, ...] = (),
                 each: str | None = None, max_rows: int = MAX_ROWS) -> None:
        self.columns = columns
        self.title = title
        self.where = where or {}
        self.exclude = exclude or {}
        self.has = has
        self.each = each
        self.max_rows = max_rows

    def rows(self, results: list) -> list[dict]:
        rows = [r for r in results if isinstance(r, dict)]
        if self.each:
            rows = [item for r in rows for item in (r.get(self.each) or [])
                    if isinstance(item, dict)]
        return [r for r in rows
                if all(r.get(k) == v for k, v in self.where.items())
                and all(r.get(k) != v for k, v in self.exclude.items())
                and all(lookup(r, k) is not None for k in self.has)]


#: Key figures per benchmark kind. A column a file's rows lack is left out of its table.
VIEWS: dict[str, list[View]] = {
    "allocation": [View(["scene", "exchange_rate_bits_per_db", "preset.bits_per_gaussian",
                         "preset.psnr", "allocated.bits_per_gaussian", "allocated.psnr"])],
    "anchors": [View(["kind", "anchors", "carm_groups", "layers", "bits_per_anchor_total",
                      "semantic_share_percent", "feature_bits_saved_percent",
                      "wall_seconds", "encode_seconds"])],
    "derived_steps": [View(["scene", "quality", "variant", "bytes", "held_out_fg_psnr_db",
                            "ratio_vs_presets", "ratio_vs_presets_bias_corrected"],
                           has=("ratio_vs_presets",), max_rows=12)],
    "sh_band_skip": [View(["scene", "quality", "file_share", "sh_band_bits_coded", "bits_now",
                           "bits_with_count", "saving", "count_entropy_bits"])],
    "sh_context_tables": [View(["scene", "quality", "file_bits_per_gaussian",
                                "sh_band_bits_per_gaussian", "bits_context_real",
                                "saving_share_of_file", "ideal_order0", "ideal_context"])],
    "sh_colour_transform": [View(["scene", "quality", "variant", "sh_band_bytes", "dc_bytes",
                                  "file_bytes", "held_out_fg_psnr_db"], max_rows=45)],
    "sh_step_scale": [View(["scene", "quality", "rest_scale", "bytes", "sh_band_bytes",
                            "held_out_fg_psnr_db", "ratio_vs_presets"])],
    "formats": [View(["scene", "format", "bytes", "bits_per_gaussian", "write_s", "read_s"])],
    "fuzz_decoder": [View(["inputs", "complete", "crashes", "hang", "max_seconds_per_input",
                           "max_seconds_alone", "max_share_of_memory_bound", "elapsed_s"])],
    "fuzz_js_receiver": [View(["seed_set", "only_seeds", "inputs", "complete",
                               "disagreements", "unread_frame_refusals", "python_outcomes.ok",
                               "python_outcomes.FormatError",
                               "receiver_max_rss_bytes", "elapsed_s"])],
    "fuzz_readers": [
        View(["inputs", "complete", "crashes", "timeouts", "typed_errors", "parsed_ok",
              "max_seconds_per_input", "max_share_of_memory_bound"]),
        View(["format", "inputs", "parsed_ok", "typed_errors", "crashes", "timeouts",
              "max_seconds_per_input", "over_memory_bound"], title="per format",
             each="formats"),
    ],
    "lod": [
        View(["file", "levels", "tiles", "encode_s", "bytes", "bits_per_gaussian",
              "ratio_to_single", "ratio_to_tiles"], title="encodes", where={"kind": "encode"}),
        View(["file", "level", "tiles", "gaussians", "share_of_file", "read_share",
              "decode_s", "typical_size", "tile_spacing", "width_at_refine_px",
              "widths_at_30db", "widths_at_35db"], title="levels",
             where={"kind": "level"}),
        View(["file", "level", "width", "psnr", "foreground_psnr", "render_s"],
             title="each level against level 0", where={"kind": "psnr"}, max_rows=40),
    ],
    "js_decode": [View(["scene", "quality", "layers", "gaussians", "color_hyperprior",
                        "js_decode_s", "python_decode_s", "ratio_js_to_python",
                        "ratio_js_first_to_python", "arrays_equal"])],
    "precision_bound": [View(["scene", "quality", "gaussians", "plain_bits_per_gaussian",
                              "oracle_held_out_bits_per_gaussian",
                              "default_distribution_bits_per_gaussian",
                              "class_map_bits_per_gaussian",
                              "best_decoded_attribute_rules_total_bits_per_gaussian",
                              "position_rules_total_bits_per_gaussian"])],
    "prior_gain": [View(["scene", "quality", "gaussians", "ratio_hyperprior_to_factorized",
                         "ratio_hyperprior_to_plain", "encode_s.hyperprior",
                         "decode_s.hyperprior"])],
    "rd": [
        View(["scene", "codec", "setting", "foreground_psnr", "bits_per_gaussian",
              "csgs_size_ratio.plain", "csgs_size_ratio.preset", "csgs_size_ratio.stacked",
              "csgs_size_ratio.uniform"],
             title="peers, and csgs's size at the peer's foreground PSNR",
             exclude={"codec": "csgs"}),
        View(["scene", "setting", "variant", "foreground_psnr", "psnr", "bits_per_gaussian",
              "encode_s", "decode_s", "size_vs_uniform_at_same_psnr",
              "size_vs_preset_at_same_psnr"],
             title="csgs's own curve", where={"codec": "csgs"}, max_rows=40),
    ],
    "refine": [View(["scene", "quality", "refine_steps", "stacked", "bytes",
                     "held_out_fg_psnr_db", "ratio_vs_presets", "cpu_s"],
                    has=("ratio_vs_presets",))],
    "scale": [View(["gaussians", "sh_degree", "quality", "tile_size",
                    "bits_per_gaussian_tiled", "tiled_size_ratio",
                    "speedup_2_workers_local", "speedup_2_workers_ray",
                    "region_bytes_fraction", "region_time_fraction",
                    "identical_across_engines"])],
    "speed": [View(["scene", "gaussians", "sh_degree", "quality", "bits_per_gaussian",
                    "encode_s", "decode_s", "decode_gaussians_per_s",
                    "decode_peak_rss_delta_mb"])],
    "train": [View(["code", "seed", "lambda", "anchors", "gaussian_slots", "bytes", "test_psnr",
                    "semantic_share", "miou_decoded", "image_miou_decoded", "cpu_s"])],
    "train_real": [View(["lambda", "anchors", "bytes", "test_psnr", "test_ssim",
                         "test_psnr_foreground", "semantic_share", "image_miou_vs_segmenter",
                         "wall_s", "cpu_s"])],
    "segment_scale": [View(["device", "gaussians", "views", "size", "iterations",
                            "seconds.render", "seconds.stage2", "seconds.instances",
                            "instances", "object_iou_mean", "semantic_share_percent_q5"])],
    "segment_auto": [View(["scene", "variant", "gaussians", "objects", "instances",
                           "click_miou_3d", "click_miou_2d", "seconds", "peak_rss_mb"])],
    "selection_real": [
        View(["masks", "variant", "coding", "selection.instance.miou_3d",
              "selection.instance.miou_2d", "semantic_share_percent"],
             title="instance selection", has=("selection.instance",), max_rows=30),
        View(["masks", "variant", "coding", "selection.cosine.miou_3d",
              "selection.cluster.miou_3d", "semantic_share_percent"],
             title="cosine and cluster selection", has=("selection.cosine",), max_rows=30)],
    "encode_time": [View(["code", "scene", "gaussians", "quality", "encode_s", "allocation_s",
                          "allocation_trials", "bytes", "sha256"], max_rows=40)],
    "train_speed": [View(["code", "device", "torch", "gpu", "stage1.size", "stage1.gaussian_slots",
                          "stage1.all_slots", "stage1.steps_per_s", "stage1.cpu_s_per_step",
                          "stage1_ops.per_step",
                          "semantic_stage.seconds", "peak_gpu_bytes"])],
    "view_pruning": [View(["scene", "quality", "view_budget", "left_out_share",
                           "bits_per_input_gaussian", "held_out_fg_psnr_db", "encode_s"])],
    "web_viewer": [View(["scene", "encode", "page", "gaussians", "first_frame_ms_median",
                         "color_frame_ms_median", "color_decode_ms_median",
                         "fetched_ratio_color_to_file"])],
    "web_levels": [View(["scene", "gaussians", "link_mbit_s", "levels_file_bytes",
                         "whole_file_bytes", "first_frame_ms_median",
                         "first_frame_share_of_file", "all_detail_ms_median",
                         "whole_color_frame_ms_median", "all_detail_over_whole"])],
}


def lookup(row: dict, path: str):
    """The value at a dotted ``path`` in ``row``, or None."""
    value = row
    for key in path.split("."):
        if not isinstance(value, dict) or key not in value:
            return None
        value = value[key]
    return value


def is_scalar(value) -> bool:
    return value is None or isinstance(value, (str, int, float, bool))


def cell(value) -> str:
    """A table cell: numbers to 4 significant digits (whole numbers from 1,000 up), text with
    its pipes escaped."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if value != value or value in (float("inf"), float("-inf")):
            return str(value)
        if abs(value) >= 1000:
            return str(round(value))
        return f"{value:.4g}"
    if isinstance(value, (list, dict)):
        if isinstance(value, list) and all(is_scalar(v) for v in value) and len(value) <= 8:
            return ", ".join(cell(v) for v in value)
        if isinstance(value, dict) and all(is_scalar(v) for v in value.values()) \
                and len(value) <= 4:
            return ", ".join(f"{k} {cell(v)}" for k, v in value.items())
        return "..."
    return " ".join(str(value).split()).replace("|", "\\|")


def table(rows: list[dict], columns: list[str], max_rows: int = MAX_ROWS) -> list[str]:
    """A markdown table of ``columns`` (those any row has) over the first ``max_rows`` rows."""
    columns = [c for c in columns if any(lookup(r, c) is not None for r in rows)]
    if not rows or not columns:
        return ["(no rows with these figures)"]
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows[:max_rows]:
        lines.append("| " + " | ".join(cell(lookup(row, c)) for c in columns) + " |")
    if len(rows) > max_rows:
        lines.append("")
        lines.append(f"({len(rows) - max_rows} more rows in the file.)")
    return lines


def generic_columns(rows: list[dict]) -> list[str]:
    """Every scalar field of ``rows``, in first-seen order."""
    columns: list[str] = []
    for row in rows:
        for key, value in row.items():
            if is_scalar(value) and key not in columns:
                columns.append(key)
    return columns


def run_key(path: Path) -> tuple[str, str, int]:
    """(date, run letter, part) of a results file; files without a date sort first."""
    match = DATED.match(path.stem)
    if not match:
        return ("", "", 0)
    return (match["date"], match["run"], int(match["part"] or 0))


def series(path: Path) -> str:
    """The series a results file belongs to: its stem without date, run letter and part."""
    match = DATED.match(path.stem)
    return match["series"] if match else path.stem


def newest(files: list[Path]) -> list[Path]:
    """The newest file of each series, keeping those of the newest date among them."""
    latest: dict[str, Path] = {}
    for path in sorted(files, key=lambda p: (run_key(p), p.name)):
        latest[series(path)] = path
    date = max(run_key(p)[0] for p in latest.values())
    return sorted((p for p in latest.values() if run_key(p)[0] == date),
                  key=lambda p: (run_key(p), p.name))


def load(folder: Path) -> dict[str, list[tuple[Path, dict]]]:
    """Benchmark kind -> [(file, document)] of the csgs-bench/1 files in ``folder``."""
    kinds: dict[str, list[tuple[Path, dict]]] = {}
    for path in sorted(folder.glob("*.json")):
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
            continue
        kinds.setdefault(str(doc.get("benchmark") or path.stem), []).append((path, doc))
    return kinds


def machine_text(machine) -> str:
    if not isinstance(machine, dict):
        return cell(machine)
    parts = []
    if machine.get("cpus") is not None:
        parts.append(f"{machine['cpus']} CPUs")
    for key in ("platform", "python", "processor"):
        if machine.get(key):
            parts.append(("Python " if key == "python" else "") + str(machine[key]))
    parts += [f"{k} {cell(v)}" for k, v in machine.items()
              if k not in ("cpus", "platform", "python", "processor")]
    return ", ".join(parts)


def settings_text(doc: dict) -> list[str]:
    """The document's scalar top-level fields (and lists of scalars) beside its rows."""
    lines = []
    for key, value in doc.items():
        if key in ("schema", "benchmark", "machine", "results"):
            continue
        if is_scalar(value) or (isinstance(value, list) and all(is_scalar(v) for v in value)):
            text = ((", ".join(cell(v) for v in value) or "none") if isinstance(value, list)
                    else cell(value))
            lines.append(f"- {key}: {text}")
    return lines


def kind_section(kind: str, files: list[tuple[Path, dict]]) -> list[str]:
    shown = newest([path for path, _ in files])
    documents = dict(files)
    older = [p for p, _ in files if p not in shown]
    lines = [f"## {kind}", ""]
    for path in shown:
        doc = documents[path]
        results = doc.get("results") if isinstance(doc.get("results"), list) else []
        lines += [f"### {path.name}", "",
                  f"Machine: {machine_text(doc.get('machine'))}.", ""]
        settings = settings_text(doc)
        if settings:
            lines += settings + [""]
        views = VIEWS.get(kind)
        if views is None:
            rows = [r for r in results if isinstance(r, dict)]
            views = [View(generic_columns(rows))]
        for view in views:
            if len(views) > 1 and not view.rows(results):
                continue  # a run without this table's rows (csgs alone, no peers)
            if view.title:
                lines += [f"{view.title[0].upper()}{view.title[1:]}:", ""]
            lines += table(view.rows(results), view.columns, view.max_rows) + [""]
    if older:
        names = ", ".join(p.name for p in sorted(older, key=lambda p: (run_key(p), p.name)))
        lines += [f"Other files: {names}.", ""]
    return lines


def other_records(folder: Path) -> list[str]:
    """Folders of logs beside the JSON files (a GPU check, say), with their files."""
    lines = []
    for path in sorted(folder.iterdir()):
        if path.is_dir():
            names = ", ".join(sorted(p.name for p in path.iterdir() if p.is_file()))
            lines.append(f"- `{path.name}/`: {names}")
    return (["## Other records", "", "Logs kept beside the JSON files:", ""] + lines + [""]
            if lines else [])


def notes(existing: str | None) -> str:
    """The hand-written notes at the end of the current page, from their heading on."""
    match = re.search(f"^{re.escape(NOTES_HEADING)}$", existing or "", re.MULTILINE)
    if match is None:
        raise SystemExit(f"{OUTPUT.relative_to(REPO)} has no '{NOTES_HEADING}' section to keep "
                         "(restore it from git before regenerating)")
    return existing[match.start():]


def render(folder: Path, existing: str | None) -> str:
    kinds = load(folder)
    lines = [
        "# Measured results",
        "",
        "<!-- Generated by benchmarks/results_md.py from benchmarks/results/*.json, down to",
        f"     '{NOTES_HEADING}'; run it after adding a results file. The notes below that",
        "     heading are written by hand and kept by the script. -->",
        "",
        "Each benchmark's newest runs, read from `benchmarks/results/`: the newest file of each",
        "series (a letter after the date marks a later run of the day), those of the newest",
        "date shown with their machine, settings and a few key figures of their rows.",
        "`benchmarks/README.md` says what each script measures; the JSON files hold every row",
        "and field. Times depend on the machine and on what else ran on it; the notes at the",
        "end say where a run shared its machine.",
        "",
        "Kinds: " + ", ".join(f"{k}" for k in sorted(kinds)) + ".",
        "",
    ]
    for kind in sorted(kinds):
        lines += kind_section(kind, kinds[kind])
    lines += other_records(folder)
    return "\n".join(lines) + "\n" + notes(existing)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 when docs/results.md differs from what would be written")
    args = parser.parse_args(argv)
    existing = OUTPUT.read_text(encoding="utf-8") if OUTPUT.is_file() else None
    if args.check and existing is None:
        print(f"{OUTPUT.relative_to(REPO)} is missing; run benchmarks/results_md.py",
              file=sys.stderr)
        return 1
    text = render(RESULTS, existing)
    if args.check:
        if text != existing:
            print(f"{OUTPUT.relative_to(REPO)} is out of date; run benchmarks/results_md.py",
                  file=sys.stderr)
            return 1
        return 0
    OUTPUT.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
