"""Step allocation along the quality ladder (issue 32): per preset, or held along the ladder?

    .venv/bin/python benchmarks/allocation_ladder.py [SCENE.ply ...] [--qualities 2 ... 9]
        [--variants presets today ladder reference curve] [--size 400x300] [--out FILE]

An experiment on the encoder's step allocation (csgs_codec/decisions/step_allocation.py): the
per-preset coordinate descent saves 0.80-0.88x the bytes at equal held-out PSNR at some
presets and nothing at their neighbours. For each scene (default: the two full-precision SH-3
captures in ../shared/data/real_sh3) and quality, one default encode per variant, each scored
by foreground PSNR on held-out views (16 orbit views at 20 degrees + 12 at 45, at ``--size``;
none used by the encoder):

- ``presets``: the preset's own steps (``Encoder(quality=q, step_allocation=False)``): the
  reference curve, encoded at qualities 1-10 so the other rows fall inside it;
- ``today``: :func:`~csgs_codec.decisions.step_allocation.allocate_steps` as this checkout
  has it (the descent on J = D + lambda R at the preset alone);
- ``ladder``: one set of offsets for the preset and its ladder neighbours: the descent's
  cost is the mean over the preset with every step moved together by -1, 0, +1 octave
  (:data:`SHIFTS`) of J / J(no offsets), each point with the exponential fit's own lambda;
  then recentred to the preset's probe error and kept at a saving of MIN_SAVING, as today
  (3x the probe renders);
- ``reference``: one scene-level allocation: today's descent at quality
  :data:`REFERENCE_QUALITY` (kept whatever it saves there), applied as offsets at every
  preset, recentred to that preset's probe error and kept at a saving of MIN_SAVING there;
- ``descent_only``: ``today`` without the coarser-grid fallback (a descent whose saving
  the probe cannot resolve keeps the preset's grid too), the rule before it;
- ``curve``: today's descent and recentring, kept when it plans MIN_SAVING fewer bits than
  the preset's own ladder (the preset with every step moved together by -2..2 half octaves,
  the points today fits lambda to) needs for the same probe error, instead of fewer bits
  than the preset at its own error: no extra probe renders.

``--probe-views N`` gives every allocating variant N probe directions and windows instead of
the encoder's 12.

The encoder's allocation function is swapped per variant, so every variant runs in the same
process on the same scene. Each row gives the file's bytes, the held-out PSNR, the wall
seconds the allocation took (``allocation_s``, 0 for the presets), the offsets chosen (half
octaves per group, grid bits for ``position``; empty: the preset kept), the allocation's
planned rate ratio and probe renders, and ``ratio_vs_presets``: the row's bytes over what the
``presets`` curve needs for its PSNR (log-size linear in PSNR; null outside the curve); below
1 the allocation pays. ``summary`` gives per scene and variant the mean and largest ratio, the
allocation seconds summed over the qualities and whether held-out PSNR rises with quality.

Measured 2026-11-27 (benchmarks/results/allocation_ladder_2026-11-27.json, qualities 2-9, mean
ratio fruit_drops / leica_sofort_top8192): today 0.957 / 0.943; ladder 0.992 / 0.930 (2.5x the
probe renders); reference 0.951 / 0.983; curve 0.965 / 0.928, with fruit_drops 7 and 8 at
1.02x and 1.06x (the probe error held, the held-out PSNR fell 0.9-1.8 dB). No variant beats
today's on both scenes, so the encoder keeps the per-preset allocation.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import REPO, document, emit  # noqa: E402
from derived_steps import HeldOut, size_at_psnr  # noqa: E402

from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions import step_allocation  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402

REAL_SH3 = REPO.parent / "shared" / "data" / "real_sh3"
DEFAULT_SCENES = [str(REAL_SH3 / "fruit_drops.ply"), str(REAL_SH3 / "leica_sofort_top8192.ply")]
#: Qualities of the reference curve (wider than the rows', so their ratios exist).
CURVE_QUALITIES = tuple(range(1, 11))
_DEFAULT_ALLOCATION = step_allocation.allocate_steps


def _today(scene, preset, **kwargs):
    """The encoder's own allocation (:func:`step_allocation.allocate_steps`, the
    per-preset descent) of ``scene`` around ``preset``: a StepAllocation."""
    return _DEFAULT_ALLOCATION(scene, preset, **kwargs)


#: Every step moved together by these half octaves: the ladder points ``ladder``'s cost
#: averages (the presets 2-9 lie 0.4-1.3 octaves apart).
SHIFTS = (-2, 0, 2)
#: The quality whose allocation ``reference`` applies at every preset (the default's).
REFERENCE_QUALITY = 5


def _probe(scene, preset, rotation_rule, cameras):
    """(the allocation's probe of ``scene`` around ``preset``, its groups, its float groups),
    or None where allocate_steps keeps the preset without probing; scenes over SAMPLE
    Gaussians are probed on allocate_steps' subset."""
    sa = step_allocation
    if len(scene) < sa.MIN_GAUSSIANS:
        return None
    if len(scene) > sa.SAMPLE:
        keep = np.sort(np.random.default_rng(0).choice(len(scene), sa.SAMPLE, replace=False))
        scene = scene.subset(keep)
    if len(np.unique(scene.positions, axis=0)) < sa.MIN_GAUSSIANS:
        return None
    probe = sa._Probe(scene, preset, rotation_rule, sa.probe_cameras(scene, cameras))
    groups = probe.groups()
    return probe, groups, [g for g in groups if g != "position"]


def _shifted(offsets: dict, k: int, float_groups: list[str]) -> dict:
    """``offsets`` with every float group's step moved by ``k`` more half octaves."""
    return {**offsets, **{g: offsets.get(g, 0) + k for g in float_groups}}


def _ladder_points(probe, float_groups) -> dict:
    """{k: (planned bits, probe MSE)} of the preset with every float step moved together by
    k = -2..2 half octaves (the points allocate_steps fits lambda to)."""
    return {k: probe.rate_distortion(_shifted({}, k, float_groups)) for k in (0, -2, -1, 1, 2)}


def _probe_with_ladder(scene, preset, rotation_rule, cameras):
    """(probe, groups, float groups, the preset's ladder points) of ``scene`` around
    ``preset`` (:func:`_probe`, :func:`_ladder_points`), or None where allocate_steps keeps
    the preset without probing."""
    setup = _probe(scene, preset, rotation_rule, cameras)
    if setup is None:
        return None
    probe, groups, float_groups = setup
    return probe, groups, float_groups, _ladder_points(probe, float_groups)


def _descend(groups: list[str], cost) -> tuple[dict, float]:
    """allocate_steps' coordinate descent on ``cost(offsets)``: (offsets, their cost)."""
    sa = step_allocation
    offsets = {g: 0 for g in groups}
    best = cost(offsets)
    for _ in range(sa.PASSES):
        moved = False
        for group in groups:
            limit = sa.MAX_BIT_OFFSET if group == "position" else sa.MAX_OFFSET
            for direction in (1, -1):
                stepped = False  # the other way only if the first step did not help
                while abs(offsets[group] + direction) <= limit:
                    trial = {**offsets, group: offsets[group] + direction}
                    c = cost(trial)
                    if c >= best:
                        break
                    best, offsets, stepped, moved = c, trial, True, True
                if stepped:
                    break
        if not moved:
            break
    return offsets, best


def _ladder(scene, preset, *, rotation_rule="footprint", cameras=None, progress=None):
    """The ``ladder`` variant's StepAllocation of ``scene`` around ``preset`` (same
    arguments as :func:`step_allocation.allocate_steps`): one set of offsets chosen by
    coordinate descent on the mean over :data:`SHIFTS` of each ladder point's J over its
    J without offsets, recentred at the preset; ``cost_ratio`` is that mean."""
    sa = step_allocation
    setup = _probe_with_ladder(scene, preset, rotation_rule, cameras)
    if setup is None:
        return sa.StepAllocation()
    probe, groups, float_groups, points = setup
    r0, d0 = points[0]
    lams = {s: sa.ladder_slope([points[s]] + [points[k] for k in points if k != s])
            for s in SHIFTS}
    if any(v is None for v in lams.values()):
        return sa.StepAllocation(trials=probe.trials)
    base = {s: points[s][1] + lams[s] * points[s][0] for s in SHIFTS}

    def cost(offsets):
        total = 0.0
        for s in SHIFTS:
            r, d = probe.rate_distortion(_shifted(offsets, s, float_groups))
            total += (d + lams[s] * r) / base[s]
        return total / len(SHIFTS)

    offsets, best = _descend(groups, cost)
    offsets, current = sa._recentre(offsets, probe.rate_distortion(offsets), d0,
                                    float_groups, probe.rate_distortion)
    rate_ratio = float(current[0] / r0) if r0 > 0 else 1.0
    if rate_ratio > 1.0 - sa.MIN_SAVING:
        offsets = {}
    return sa.StepAllocation(dict(offsets), float(lams[0]), probe.trials, float(best),
                             rate_ratio)


def _reference(scene, preset, *, rotation_rule="footprint", cameras=None, progress=None):
    """The ``reference`` variant's StepAllocation of ``scene`` around ``preset``: today's
    descent at :data:`REFERENCE_QUALITY` (kept whatever it saves there), applied as offsets
    at ``preset``, recentred to its probe error and kept when it plans MIN_SAVING fewer bits
    there; ``trials`` counts both probes' renders."""
    from csgs_codec.decisions.presets import PRESETS

    sa = step_allocation
    saved = sa.MIN_SAVING
    sa.MIN_SAVING = -1.0
    try:
        ref = _today(scene, PRESETS[REFERENCE_QUALITY], rotation_rule=rotation_rule,
                     cameras=cameras)
    finally:
        sa.MIN_SAVING = saved
    setup = _probe(scene, preset, rotation_rule, cameras) if ref.offsets else None
    if setup is None:
        return ref
    probe, groups, float_groups = setup
    r0, d0 = probe.rate_distortion({})
    offsets = {g: ref.offsets.get(g, 0) for g in groups}
    offsets, current = sa._recentre(offsets, probe.rate_distortion(offsets), d0,
                                    float_groups, probe.rate_distortion)
    rate_ratio = float(current[0] / r0) if r0 > 0 else 1.0
    if rate_ratio > 1.0 - sa.MIN_SAVING:
        offsets = {}
    return sa.StepAllocation(dict(offsets), ref.lambda_, ref.trials + probe.trials, 1.0,
                             rate_ratio)


def ladder_rate(points: dict, error: float) -> float:
    """Planned bits the preset's own ladder (``points``, :func:`_ladder_points`) needs for
    probe MSE ``error``: log-bits linear in log-MSE between the points, the exponential fit
    D = exp(a + b R) beyond them."""
    pts = sorted((np.log(d), np.log(r)) for r, d in points.values())
    x = np.log(error)
    if pts[0][0] <= x <= pts[-1][0]:
        return float(np.exp(np.interp(x, [p[0] for p in pts], [p[1] for p in pts])))
    rates = np.array([r for r, _ in points.values()])
    slope, intercept = np.polyfit(rates, np.log([d for _, d in points.values()]), 1)
    return float((x - intercept) / slope)


def _curve(scene, preset, *, rotation_rule="footprint", cameras=None, progress=None):
    """The ``curve`` variant's StepAllocation of ``scene`` around ``preset``: today's descent
    and recentring, kept when it plans MIN_SAVING fewer bits than the preset's own ladder
    needs for the same probe error (:func:`ladder_rate`) instead of fewer than the preset at
    its (higher or equal) error: the recentring moves in half octaves, so the allocation
    lands up to half an octave finer than the preset and today's ratio counts that quality
    as rate. ``rate_ratio`` is the ratio at equal probe error."""
    sa = step_allocation
    setup = _probe_with_ladder(scene, preset, rotation_rule, cameras)
    if setup is None:
        return sa.StepAllocation()
    probe, groups, float_groups, points = setup
    r0, d0 = points[0]
    lam = sa.ladder_slope(list(points.values()))
    if lam is None:
        return sa.StepAllocation(trials=probe.trials)

    def cost(offsets):
        r, d = probe.rate_distortion(offsets)
        return d + lam * r

    offsets, best = _descend(groups, cost)
    offsets, current = sa._recentre(offsets, probe.rate_distortion(offsets), d0,
                                    float_groups, probe.rate_distortion)
    rate_ratio = float(current[0] / ladder_rate(points, current[1])) if current[1] > 0 else 1.0
    if rate_ratio > 1.0 - sa.MIN_SAVING:
        offsets = {}
    return sa.StepAllocation(dict(offsets), float(lam), probe.trials,
                             float(cost(offsets) / (d0 + lam * r0)), rate_ratio)


def _descent_only(scene, preset, **kwargs):
    """The ``descent_only`` variant: today's allocation without its coarser-grid fallback
    (where the descent's saving is below what the probe resolves, the preset's steps and
    grid both), the encoder's rule before 2026-11-27's second change."""
    sa = step_allocation
    fallback = sa._coarser_grid
    sa._coarser_grid = lambda r0, d0, cost, evaluate: ({}, (r0, d0))
    try:
        return _today(scene, preset, **kwargs)
    finally:
        sa._coarser_grid = fallback


#: Allocation function of each allocating variant (None: the preset's steps).
VARIANTS = {"presets": None, "today": _today, "ladder": _ladder, "reference": _reference,
            "curve": _curve, "descent_only": _descent_only}


def encode_row(scene, held: HeldOut, quality: int, variant: str) -> dict:
    """One default encode of ``scene`` at ``quality`` under ``variant``, scored.

    Returns:
        The row without its ratio: quality, variant, bytes, held-out foreground PSNR (dB),
        allocation seconds (wall), offsets, and the allocation's planned rate ratio.
    """
    allocate = VARIANTS[variant]
    spent = [0.0]
    if allocate is None:
        encoder = Encoder(quality=quality, step_allocation=False)
    else:
        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return allocate(*args, **kwargs)
            finally:
                spent[0] += time.perf_counter() - start

        step_allocation.allocate_steps = timed
        # step_allocation=True: SH-0 scenes are allocated too (the default skips them).
        encoder = Encoder(quality=quality, step_allocation=True)
    try:
        result = encoder.encode_with_report(scene)
    finally:
        step_allocation.allocate_steps = _DEFAULT_ALLOCATION
    allocation = result.allocation
    return {"quality": quality, "variant": variant, "bytes": len(result.data),
            "held_out_fg_psnr_db": held.psnr(result.reconstruction),
            "allocation_s": spent[0],
            "offsets": {} if allocation is None else {k: v for k, v in
                                                      allocation.offsets.items() if v},
            "planned_rate_ratio": None if allocation is None else allocation.rate_ratio,
            "probe_renders": None if allocation is None else allocation.trials}


def run_scene(path: str, qualities: list[int], variants: list[str], size: tuple[int, int],
              log) -> list[dict]:
    """Rows of one scene: the preset curve (qualities 1-10 at least), then each allocating
    variant at ``qualities``; ``ratio_vs_presets`` filled in."""
    scene = read_ply(path)
    name = Path(path).name
    held = HeldOut(scene, *size)
    rows = []
    curve_qualities = sorted(set(CURVE_QUALITIES) | set(qualities))
    for variant in variants:
        for quality in curve_qualities if variant == "presets" else qualities:
            row = {"scene": name, **encode_row(scene, held, quality, variant)}
            rows.append(row)
            log(row)
    curve = [(r["held_out_fg_psnr_db"], r["bytes"]) for r in rows if r["variant"] == "presets"]
    for row in rows:
        needed = size_at_psnr(curve, row["held_out_fg_psnr_db"]) if curve else float("nan")
        row["ratio_vs_presets"] = None if np.isnan(needed) else row["bytes"] / needed
    return [r for r in rows if r["variant"] != "presets" or r["quality"] in qualities] + \
        [dict(r, curve_only=True) for r in rows
         if r["variant"] == "presets" and r["quality"] not in qualities]


def summary(rows: list[dict]) -> list[dict]:
    """Per scene and variant: mean ratio_vs_presets over the rows that have one, the total
    allocation seconds, and whether held-out PSNR rises with quality (the ladder's order)."""
    out = []
    for scene in sorted({r["scene"] for r in rows}):
        for variant in sorted({r["variant"] for r in rows}):
            mine = sorted((r for r in rows if r["scene"] == scene and r["variant"] == variant
                           and not r.get("curve_only")), key=lambda r: r["quality"])
            ratios = [r["ratio_vs_presets"] for r in mine if r["ratio_vs_presets"] is not None]
            psnr = [r["held_out_fg_psnr_db"] for r in mine]
            out.append({"scene": scene, "variant": variant,
                        "mean_ratio_vs_presets": float(np.mean(ratios)) if ratios else None,
                        "max_ratio_vs_presets": float(np.max(ratios)) if ratios else None,
                        "allocation_s": float(sum(r["allocation_s"] for r in mine)),
                        "ladder_order_kept": bool(np.all(np.diff(psnr) > 0))})
    return out


def main() -> int:
    """Parse arguments, encode every scene under every variant, write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=DEFAULT_SCENES)
    parser.add_argument("--qualities", type=int, nargs="+", default=list(range(2, 10)))
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--size", default="400x300")
    parser.add_argument("--probe-views", type=int, default=None,
                        help="probe directions and windows of every allocating variant "
                             "(default: the encoder's PROBE_VIEWS)")
    parser.add_argument("--out")
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    variants = ["presets"] + [v for v in args.variants if v != "presets"]
    if args.probe_views:  # a denser probe for every variant (the encoder keeps its own)
        step_allocation.PROBE_DIRECTIONS = step_allocation.PROBE_VIEWS = args.probe_views

    def log(row: dict) -> None:
        print(f"{row['scene']} q{row['quality']} {row['variant']}: {row['bytes']} B, "
              f"{row['held_out_fg_psnr_db']:.2f} dB, alloc {row['allocation_s']:.1f} s, "
              f"{row['offsets']}", file=sys.stderr, flush=True)

    rows: list[dict] = []
    for path in args.scenes:
        rows += run_scene(path, args.qualities, variants, size, log)
        # a run stopped later still leaves the scenes it finished
        emit(document("allocation_ladder", rows, settings=vars(args),
                      held_out_views=f"16 @20deg + 12 @45deg, {args.size}",
                      summary=summary(rows)), args.out)
    for line in summary(rows):
        print(line, file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
