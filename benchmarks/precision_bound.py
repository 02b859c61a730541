"""How far can render-aware precision go? An oracle bound on per-value step allocation.

For each scene: J2, the weight of each coded value's squared error in the rendered squared
error (csgs_codec/render/jacobian_sensitivity.py), over the held-out scoring views (16 orbit
views at 20 degrees + 12 at 45 degrees) and over the default viewing distribution the encoder
allocates on. For each quality, the plain encode gives each attribute group's bits per value
R_g and its rounding error e (coded value minus original, in coding form).

The model (high-rate, first order): a value of group g quantized with step D has squared error
D^2/12 and costs R_g + log2(D_g / D) bits, where D_g = sqrt(12 mean(e^2)) is the group's
effective step in the plain encode. The rendered squared error is sum J2 e^2. Against the
plain encode's modelled error (sum J2 D_g^2 / 12, checked against real renders in
``first_order_check``), two allocations are costed at the same rendered error:

- ``oracle_held_out``: reverse water-filling on the held-out views' J2 themselves, each
  value its own step, side information free, values no view sees dropped: no allocation
  scored on those views can save more at high rate;
- ``default_distribution``: steps water-filled on the default distribution's J2, scored on
  the held-out views (what the encoder could reach without knowing the scoring views, still
  with free side information).

Two structured allocations an encoder could signal are costed the same way: one step class
per Gaussian shared by all its values (``class_map_*``: a class map, its zeroth-order entropy
reported as side information), and steps derived from decoded scales and opacity (each
candidate rule of :func:`rule_features` per group, ``derived_rule_saving_*``; the best rule
per group summed, and on top of the class map). Rules named ``*_by_position`` and
``*_and_position`` stand for steps a position-only predictor (the color hyperprior's
network) would supply: a neighbourhood estimate of each Gaussian's J2 that never sees its
own (:func:`position_features`; optimistic, the network's bytes are not counted).

Rows give the plain bits per Gaussian and each allocation's bits at equal held-out error, and
their fractions of the plain bits. ``--rd FILE`` (an rd.py document with plain csgs curves
and peers, held-out scoring) adds, per peer, the plain ratio at the peer's PSNR times each
fraction interpolated there: the size ratio each allocation would give against that peer.
``--rows`` re-reads saved rows instead of measuring.

    .venv/bin/python benchmarks/precision_bound.py --scenes donut plant --qualities 5 7 8 9 \\
        --cache /tmp/j2 --out bound.json
    .venv/bin/python benchmarks/precision_bound.py --rows bound.json --rd rd.json --out b.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import FULL_PRECISION, SCENES, document, emit, held_out_views  # noqa: E402

from csgs_codec.attributes.attribute_forms import (  # noqa: E402
    normalize_quaternions,
    quaternion_to_smallest_three,
)
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402
from csgs_codec.render.jacobian_sensitivity import jacobian_sensitivity  # noqa: E402
from csgs_codec.render.rasterizer import render  # noqa: E402
from csgs_codec.render.view_distribution import default_distribution  # noqa: E402

#: Chunk type that carries each attribute group's bits.
CHUNKS = {"position": ("GEOM", "OUTL", "OUTQ"), "dc": ("SHDC",), "band1": ("SHBA",),
          "band2": ("SHBB",), "band3": ("SHBC",), "opacity": ("OPAC",), "scale": ("SCAL",),
          "rotation": ("ROTN",)}


def coded_errors(original, result) -> dict[str, np.ndarray]:
    """(N, C) rounding error of each group's coded values (decoded minus original, in
    coding form, decoded Gaussians in the input's order)."""
    recon, order = result.reconstruction, result.order
    ref = original.subset(order)
    n = len(recon)
    errors = {"position": recon.positions - ref.positions,
              "dc": recon.sh_dc - ref.sh_dc,
              "opacity": (recon.opacity - ref.opacity).reshape(n, 1),
              "scale": recon.scales - ref.scales}
    axis, rest = quaternion_to_smallest_three(ref.rotations)
    q = normalize_quaternions(recon.rotations).astype(np.float64)
    rows = np.arange(n)
    q *= np.where(q[rows, axis] < 0, -1.0, 1.0)[:, None]
    keep = np.ones((n, 4), bool)
    keep[rows, axis] = False
    errors["rotation"] = q[keep].reshape(n, 3) * np.sqrt(2.0) - rest
    first = 0
    for band in range(1, 4):
        count = 2 * band + 1
        if ref.sh_rest.shape[1] >= first + count:
            errors[f"band{band}"] = (recon.sh_rest[:, first:first + count]
                                     - ref.sh_rest[:, first:first + count]).reshape(n, -1)
        first += count
    return {k: np.asarray(v, np.float64) for k, v in errors.items()}


def level_for(error, target: float, low: float, high: float, *, rising: bool = True,
              steps: int = 200) -> float:
    """Bisection: the level in [low, high] at which ``error(level)`` (monotone: rising or
    falling with the level) meets ``target``, on the side where it stays within it."""
    for _ in range(steps):
        mid = 0.5 * (low + high)
        if (error(mid) > target) == rising:
            high = mid
        else:
            low = mid
    return low if rising else high


def water_fill(variance_like: np.ndarray, target: float) -> tuple[float, np.ndarray]:
    """Reverse water-filling: the level theta with sum(min(theta, S)) = ``target`` and each
    value's distortion min(theta, S) (S: the weighted error a value costs at zero rate)."""
    theta = level_for(lambda t: np.minimum(t, variance_like).sum(), target, 0.0,
                      float(variance_like.max()))
    return theta, np.minimum(theta, variance_like)


def rate_bits(variance_like: np.ndarray, distortion: np.ndarray) -> float:
    """Bits of values whose zero-rate error is ``variance_like`` at ``distortion``."""
    live = (variance_like > 0) & (distortion > 0)
    return float(0.5 * np.log2(variance_like[live] / distortion[live]).sum())


def zero_rate_error(r_g: float, delta2: float) -> float:
    """Squared error of a value left at zero rate: the group's variance implied by its bits
    per value ``r_g`` at effective step^2 ``delta2`` (high-rate model)."""
    return delta2 * 2.0 ** (2 * r_g) / 12.0


def at_shift(r_g: float, delta2: float, shift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bits, squared error) of values whose step is 2^-``shift`` times the group's (bits
    per value ``r_g``, effective step^2 ``delta2``); at zero bits the error is the
    variance."""
    coded = r_g + shift > 0
    e2 = np.where(coded, delta2 * 2.0 ** (-2 * shift) / 12.0, zero_rate_error(r_g, delta2))
    return np.maximum(0.0, r_g + shift), e2


def joint_bins(features: list[tuple[np.ndarray, int]]) -> tuple[np.ndarray, int]:
    """(bin of each value, number of bins) from the joint quantile bins of ``features``
    ((feature, bins) pairs of one shape; their bins multiply)."""
    which = np.zeros(features[0][0].shape, np.int64)
    bins = 1
    for feature, count in features:
        edges = np.quantile(feature, np.linspace(0, 1, count + 1)[1:-1])
        which = which * count + np.searchsorted(edges, feature)
        bins *= count
    return which, bins


def sensitivities(name: str, original, held, allocation, cache: Path | None):
    """J2 on the held-out and allocation views ({group: (N, C)} each) and the seconds the
    pass took, read from ``cache`` when it holds them."""
    path = None if cache is None else cache / f"{name}_{held[0].width}x{held[0].height}.npz"
    if path is not None and path.exists():
        data = np.load(path)
        split = lambda prefix: {k[len(prefix):]: data[k] for k in data.files  # noqa: E731
                                if k.startswith(prefix)}
        return split("held_"), split("alloc_"), float(data["seconds"])
    start = time.perf_counter()
    j_held = jacobian_sensitivity(original, held).values
    j_alloc = jacobian_sensitivity(original, allocation).values
    seconds = time.perf_counter() - start
    if path is not None:
        cache.mkdir(parents=True, exist_ok=True)
        np.savez(path, seconds=seconds, **{f"held_{k}": v for k, v in j_held.items()},
                 **{f"alloc_{k}": v for k, v in j_alloc.items()})
    return j_held, j_alloc, seconds


def bound_rows(name: str, original, qualities: list[int], width: int, height: int,
               cache: Path | None = None) -> list[dict]:
    """Rows of one scene (see the module docstring)."""
    held = held_out_views(original, width, height)
    allocation = default_distribution(original, size=(width, height)).cameras
    j_held, j_alloc, sensitivity_s = sensitivities(name, original, held, allocation, cache)
    print(f"{name}: sensitivities {sensitivity_s:.0f} s", file=sys.stderr)
    refs = [render(original, c, backend="numba").image.astype(np.float64) for c in held]
    rows = []
    for quality in qualities:
        result = Encoder(quality=quality).encode_with_report(original)
        n_in = len(original)
        errors = coded_errors(original, result)
        order = result.order
        recon_sse = sum(float(((render(result.reconstruction, c, backend="numba").image
                                .astype(np.float64) - ref) ** 2).sum())
                        for c, ref in zip(held, refs))
        # Per value of every group: J2 (held, alloc), zero-rate error S and modelled error.
        s_held, s_alloc, j_h_all, j_a_all, variance_all = [], [], [], [], []
        per_group = []
        plain_bits, modelled, first_order = 0.0, 0.0, 0.0
        groups = {}
        for group, err in errors.items():
            bits = sum(result.stream_bytes.get(c, 0) for c in CHUNKS[group]) * 8.0
            count = err.size
            r_g = bits / count
            delta2 = 12.0 * float(np.mean(err ** 2))
            if delta2 <= 0:
                continue
            variance = zero_rate_error(r_g, delta2)
            jh, ja = j_held[group][order], j_alloc[group][order]
            plain_bits += bits
            modelled += float((jh * delta2 / 12.0).sum())
            first_order += float((jh * err ** 2).sum())
            s_held.append((jh * variance).ravel())
            s_alloc.append((ja * variance).ravel())
            j_h_all.append(jh.ravel())
            j_a_all.append(ja.ravel())
            variance_all.append(np.full(count, variance))
            per_group.append((ja, jh, r_g, delta2))
            live = jh[jh > 0]
            groups[group] = {"bits_per_value": r_g, "effective_step": float(np.sqrt(delta2)),
                             "j2_am_over_gm_bits": float(0.5 * np.log2(
                                 live.mean() / np.exp(np.log(live).mean()))) if live.size
                             else None}
        s_h, s_a = np.concatenate(s_held), np.concatenate(s_alloc)
        j_h, j_a = np.concatenate(j_h_all), np.concatenate(j_a_all)
        _, d_oracle = water_fill(s_h, modelled)
        oracle_bits = rate_bits(s_h, d_oracle)
        alloc_bits = _transferred_bits(s_a, j_a, j_h, np.concatenate(variance_all), modelled)
        classes = class_allocation(per_group, modelled)
        features = rule_features(result.reconstruction)
        index = dict(zip(groups, per_group))
        features.update(position_features(result.reconstruction, features,
                                           {g: v[0] for g, v in index.items()}))
        rules = {}
        best: dict[str, tuple[float, str]] = {}
        for rule, (group, feature) in features.items():
            if group in index:
                ja, jh, r_g, delta2 = index[group]
                rules[rule] = rule_saving(feature, ja, jh, r_g, delta2) / n_in
                if rules[rule] > best.get(group, (0.0, ""))[0]:
                    best[group] = (rules[rule], rule)
        # The best rule of each group on top of one class per Gaussian.
        combined = class_allocation(per_group, modelled, [
            rule_shifts(features[best[g][1]][1], index[g][0]) if g in best else None
            for g in groups])
        for group, (ja, jh, r_g, delta2) in zip(groups, per_group):
            # The same two allocations within this group alone (the others unchanged).
            variance = zero_rate_error(r_g, delta2)
            target = float((jh * delta2 / 12.0).sum())
            plain_g = r_g * jh.size
            _, d = water_fill((jh * variance).ravel(), target)
            alloc = _transferred_bits((ja * variance).ravel(), ja.ravel(), jh.ravel(),
                                      np.full(jh.size, variance), target)
            groups[group]["oracle_saving_bits_per_gaussian"] = \
                (plain_g - rate_bits((jh * variance).ravel(), d)) / n_in
            groups[group]["default_distribution_saving_bits_per_gaussian"] = \
                (plain_g - alloc) / n_in
        other = 8.0 * len(result.data) - plain_bits
        row = {"scene": name, "full_precision_scene": name in FULL_PRECISION,
               "quality": quality, "gaussians": n_in,
               "plain_bits_per_gaussian": 8.0 * len(result.data) / n_in,
               "oracle_held_out_bits_per_gaussian": (oracle_bits + other) / n_in,
               "default_distribution_bits_per_gaussian": (alloc_bits + other) / n_in,
               "class_map_bits_per_gaussian": (classes["bits"] + other) / n_in,
               "class_map_side_info_bits_per_gaussian": classes["class_map_bits"] / n_in,
               "class_map_classes": classes["classes_used"],
               "groups": groups,
               "derived_rule_saving_bits_per_gaussian": rules,
               "derived_rules_best_total_bits_per_gaussian": sum(v for v, _ in best.values()),
               "class_map_with_rules_bits_per_gaussian": (combined["bits"] + other) / n_in,
               "class_map_with_rules_side_info_bits_per_gaussian":
                   combined["class_map_bits"] / n_in,
               "first_order_check": {"rendered_sse": recon_sse,
                                     "first_order_sse": first_order,
                                     "modelled_sse": modelled},
               "sensitivity_s": sensitivity_s}
        row["oracle_fraction"] = row["oracle_held_out_bits_per_gaussian"] / \
            row["plain_bits_per_gaussian"]
        row["default_distribution_fraction"] = row["default_distribution_bits_per_gaussian"] / \
            row["plain_bits_per_gaussian"]
        row["class_map_fraction"] = (row["class_map_bits_per_gaussian"]
                                     + row["class_map_side_info_bits_per_gaussian"]) / \
            row["plain_bits_per_gaussian"]
        print(row, file=sys.stderr)
        rows.append(row)
    return rows


def _transferred_bits(s_alloc, j_alloc, j_held, variance, target: float) -> float:
    """Bits of the allocation water-filled on the allocation views' J2 whose held-out
    error equals ``target`` (bisection on the allocation's level)."""
    def held_error(theta: float) -> tuple[float, float]:
        d = np.minimum(theta, s_alloc)
        coded = (d < s_alloc) & (j_alloc > 0)
        e2 = np.where(coded, d / np.where(j_alloc > 0, j_alloc, 1.0), variance)
        return float((j_held * e2).sum()), rate_bits(s_alloc, d)

    theta = level_for(lambda t: held_error(t)[0], target, 0.0, float(s_alloc.max()))
    return held_error(theta)[1]


#: Step shifts a per-Gaussian class may take (octaves finer when positive).
CLASS_SHIFTS = np.arange(-8.0, 4.01, 0.5)


def class_allocation(groups: list[tuple[np.ndarray, np.ndarray, float, float]],
                     target: float, shifts: list[np.ndarray | None] | None = None) -> dict:
    """One step class per Gaussian shared by all its attributes (what a class map codes):
    each Gaussian picks the shift k of :data:`CLASS_SHIFTS` (every step times 2^-k) that
    minimises rate + lambda x allocation-view error; lambda is set so the held-out error
    equals ``target``. Returns the coded bits and the class map's zeroth-order entropy.

    ``groups``: per group, (J2 on the allocation views (N, C), J2 held-out (N, C), bits per
    value R_g, effective step^2 D_g^2). ``shifts``: per group, a derived per-value shift
    (N, C) added to the class's (octaves finer), or None."""
    n = groups[0][0].shape[0]
    rate = np.zeros((n, len(CLASS_SHIFTS)))
    d_alloc = np.zeros_like(rate)
    d_held = np.zeros_like(rate)
    shifts = shifts or [None] * len(groups)
    for (j_alloc, j_held, r_g, delta2), extra in zip(groups, shifts):
        extra = np.zeros(j_alloc.shape) if extra is None else extra
        for column, k in enumerate(CLASS_SHIFTS):
            bits, e2 = at_shift(r_g, delta2, k + extra)
            rate[:, column] += bits.sum(1)
            d_alloc[:, column] += (j_alloc * e2).sum(1)
            d_held[:, column] += (j_held * e2).sum(1)
    rows = np.arange(n)

    def pick(log_lambda: float) -> np.ndarray:
        return np.argmin(rate + np.exp(log_lambda) * d_alloc, axis=1)

    # The held-out error falls as lambda rises; search it on a log scale.
    choice = pick(level_for(lambda x: d_held[rows, pick(x)].sum(), target, np.log(1e-6),
                            np.log(1e18), rising=False))
    counts = np.bincount(choice, minlength=len(CLASS_SHIFTS))
    p = counts[counts > 0] / n
    return {"bits": float(rate[rows, choice].sum()),
            "class_map_bits": float(-(p * np.log2(p)).sum() * n),
            "classes_used": int((counts > 0).sum())}


def rule_features(ref) -> dict[str, tuple[str, list[tuple[np.ndarray, int]]]]:
    """Candidate features a decoder could derive a value's step from: name -> (group,
    [(feature (N, C) per value, quantile bins)]), from the decoded scene ``ref`` (decoded
    order). Several features bin jointly (their bins multiply)."""
    log_s = np.asarray(ref.scales, np.float64)
    n = len(log_s)
    big = log_s.max(1, keepdims=True)
    small = log_s.min(1, keepdims=True)
    mid = np.sort(log_s, 1)[:, 1:2]
    alpha = 1.0 / (1.0 + np.exp(-np.asarray(ref.opacity, np.float64).reshape(n, 1)))
    log_alpha = np.log(np.maximum(alpha, 1e-12))
    area = big + mid
    footprint = area + 2.0 * log_alpha
    shear = np.log(np.maximum(np.sinh(big - small), 1e-6))

    def per(values: np.ndarray, channels: int) -> np.ndarray:
        return np.repeat(values, channels, 1)

    return {
        "scale_by_log_scale": ("scale", [(log_s, 16)]),
        "scale_by_relative_log_scale": ("scale", [(log_s - big, 16)]),
        "scale_by_log_scale_and_opacity": ("scale", [(log_s, 16), (per(log_alpha, 3), 4)]),
        "rotation_by_anisotropy": ("rotation", [(per(big - small, 3), 16)]),
        "rotation_by_largest_log_scale": ("rotation", [(per(big, 3), 16)]),
        "rotation_by_largest_and_anisotropy": ("rotation", [(per(big, 3), 8),
                                                            (per(big - small, 3), 8)]),
        "rotation_by_area_shear_opacity": ("rotation",
                                           [(per(area + 2 * shear + 2 * log_alpha, 3), 16)]),
        "position_by_largest_log_scale": ("position", [(per(big, 3), 16)]),
        "position_by_opacity": ("position", [(per(log_alpha, 3), 16)]),
        "position_by_opacity_and_largest": ("position", [(per(log_alpha, 3), 8),
                                                         (per(big, 3), 8)]),
        "dc_by_largest_log_scale": ("dc", [(per(big, 3), 16)]),
        "dc_by_footprint_and_opacity": ("dc", [(per(footprint, 3), 16)]),
        "dc_by_area_and_opacity": ("dc", [(per(area, 3), 8), (per(log_alpha, 3), 8)]),
        "opacity_by_opacity": ("opacity", [(alpha, 16)]),
        "opacity_by_area_and_opacity": ("opacity", [(area, 8), (alpha, 8)]),
    }


def position_smoothed(positions: np.ndarray, values: np.ndarray, *, members: int = 4,
                      levels: int = 12) -> np.ndarray:
    """(N,) leave-one-out mean of ``values`` over the Gaussians in the same voxel, at the
    finest of ``levels`` octree depths where the voxel holds at least ``members`` others:
    what a predictor that sees only a Gaussian's position (and its neighbours' values, never
    its own) could know. An optimistic stand-in for the color hyperprior's small network."""
    lo = positions.min(0)
    extent = float((positions.max(0) - lo).max()) or 1.0
    out = np.full(len(values), float(np.mean(values)))
    done = np.zeros(len(values), bool)
    for depth in range(levels, 0, -1):
        cells = np.minimum(((positions - lo) / extent * (1 << depth)).astype(np.int64),
                           (1 << depth) - 1)
        key = (cells[:, 0] << 42) | (cells[:, 1] << 21) | cells[:, 2]
        _, which, count = np.unique(key, return_inverse=True, return_counts=True)
        total = np.bincount(which, weights=values)
        ok = ~done & (count[which] > members)
        out[ok] = (total[which][ok] - values[ok]) / (count[which][ok] - 1)
        done |= ok
    return out


def position_features(ref, features: dict, j_alloc: dict[str, np.ndarray]) -> dict:
    """Rules whose feature a position-only predictor could supply: per group, the
    neighbourhood estimate of the Gaussian's log allocation-view J2 (:func:`position_smoothed`,
    16 quantile bins), alone (``<group>_by_position``) and joint with the decoded-attribute
    rules of rotation and DC (4 x 8 bins, ``..._and_position``), as the hyperprior predicting
    a step from position on top of mode 7's rule would."""
    positions = np.asarray(ref.positions, np.float64)
    out = {}
    for group, ja in j_alloc.items():
        log_j = np.log(np.maximum(ja.sum(1), 1e-30))
        predicted = np.repeat(position_smoothed(positions, log_j)[:, None], ja.shape[1], 1)
        out[f"{group}_by_position"] = (group, [(predicted, 16)])
        for rule in ("rotation_by_area_shear_opacity", "dc_by_area_and_opacity"):
            if features[rule][0] == group:
                parts = [(predicted, 4)] + [(f, 8) for f, _ in features[rule][1]][:1]
                out[f"{rule}_and_position"] = (group, parts)
    return out


def rule_shifts(features: list[tuple[np.ndarray, int]], j_alloc: np.ndarray) -> np.ndarray:
    """(N, C) step shift of each value (octaves finer, median 0) from its features' joint
    quantile bin: half the log2 of the bin's mean allocation-view J2 (high-rate optimum)."""
    which, bins = joint_bins(features)
    mean_j = np.bincount(which.ravel(), weights=j_alloc.ravel(), minlength=bins) / \
        np.maximum(np.bincount(which.ravel(), minlength=bins), 1)
    log_mean = np.log2(np.maximum(mean_j, 1e-300))
    return 0.5 * (log_mean - np.median(log_mean))[which]


def rule_saving(features: list[tuple[np.ndarray, int]], j_alloc: np.ndarray,
                j_held: np.ndarray, r_g: float, delta2: float) -> float:
    """Bits saved in one group at equal held-out error when each value's step follows
    :func:`rule_shifts`, against the group's uniform step."""
    shift = rule_shifts(features, j_alloc)
    target = float((j_held * delta2 / 12.0).sum())

    def cost(offset: float) -> tuple[float, float]:
        bits, e2 = at_shift(r_g, delta2, shift + offset)
        return float((j_held * e2).sum()), float(bits.sum())

    offset = level_for(lambda o: cost(o)[0], target, -40.0, 40.0, rising=False, steps=100)
    return r_g * j_held.size - cost(offset)[1]


def _fractions(row: dict) -> dict[str, float]:
    """Each allocation's bits as a fraction of the plain encode's (side information in)."""
    plain = row["plain_bits_per_gaussian"]
    return {
        "oracle_held_out": row["oracle_fraction"],
        "default_distribution": row["default_distribution_fraction"],
        "class_map_with_rules": (row["class_map_with_rules_bits_per_gaussian"]
                                 + row["class_map_with_rules_side_info_bits_per_gaussian"])
        / plain,
        "derived_rules": 1.0 - row["derived_rules_best_total_bits_per_gaussian"] / plain,
    }


def peer_bounds(rd_path: str, rows: list[dict]) -> list[dict]:
    """Per peer row of the rd document: the plain ratio, and per allocation that ratio times
    the allocation's fraction interpolated at the peer's PSNR on the plain curve."""
    doc = json.loads(Path(rd_path).read_text())
    out = []
    for peer in doc["results"]:
        if peer["codec"] == "csgs":
            continue
        plain = (peer.get("csgs_size_ratio") or {}).get("plain")
        mine = {r["quality"]: _fractions(r) for r in rows if r["scene"] == peer["scene"]}
        curve = sorted((r["foreground_psnr"], int(r["setting"].split()[-1]))
                       for r in doc["results"] if r["codec"] == "csgs"
                       and r["scene"] == peer["scene"] and r.get("variant") == "plain"
                       and int(r["setting"].split()[-1]) in mine)
        if plain is None or not curve:
            continue
        ratios = {}
        for name in next(iter(mine.values())):
            f = float(np.interp(peer["foreground_psnr"], [p for p, _ in curve],
                                [mine[q][name] for _, q in curve]))
            ratios[name] = plain * f
        out.append({"scene": peer["scene"], "peer": peer["codec"],
                    "peer_foreground_psnr": peer["foreground_psnr"], "plain_ratio": plain,
                    "stacked_ratio": (peer.get("csgs_size_ratio") or {}).get("stacked"),
                    "allocation_ratios": ratios})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["donut"])
    parser.add_argument("--qualities", nargs="+", type=int, default=[5, 7, 8, 9])
    parser.add_argument("--size", default="400x300",
                        help="render size of both view sets (J2 and the SSE check)")
    parser.add_argument("--rd", default=None, help="rd.py document to bound its peer ratios")
    parser.add_argument("--cache", default=None,
                        help="folder to keep the sensitivities in (reused when present)")
    parser.add_argument("--rows", nargs="+", default=None, metavar="JSON",
                        help="take the rows of these precision_bound documents instead of "
                             "measuring (to bound an rd document's peers with --rd)")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    rows = []
    for path in args.rows or []:
        rows += json.loads(Path(path).read_text())["results"]
    for name in [] if args.rows else args.scenes:
        rows += bound_rows(name, read_ply(SCENES / f"{name}.ply"), args.qualities, width,
                           height, None if args.cache is None else Path(args.cache))
    extra = {"peers": peer_bounds(args.rd, rows)} if args.rd else {}
    emit(document("precision_bound", rows, size=args.size,
                  held_out_views="16 @20deg + 12 @45deg",
                  allocation_views="default viewing distribution", **extra), args.out)


if __name__ == "__main__":
    main()
