"""Two encoder rules for the SH bands of SH-3 scenes that do not pay (issue 32), in real encodes.

    .venv/bin/python benchmarks/sh_rest_rules.py SCENE.ply [--qualities 3 5 7]
        [--strengths 0.5 1.0] [--thetas 0.4 0.3] [--size 400x300] [--out FILE]

An experiment, not a codec feature: it swaps two pieces of the default encoder (quality
presets 2-8 give the reference curve, each with step allocation, the hyperprior and the
colour transform as the default has them) and scores every encode on held-out views (16 orbit
views at 20 degrees + 12 at 45, at ``--size``, none used by the encoder):

- ``scored`` (strength s): each Gaussian's SH-band steps follow a class of its decoded
  footprint, the scored steps rotations use (FORMAT §12.8), with 8 quantile bins of
  u = log area + 2 log opacity and a step multiplier of the class mean of e^u to the power
  -s/2, rate-neutral by count: a colour error's image energy grows with the Gaussian's area
  times its opacity squared. The reconstruction is the encoder's own (the format carries
  scored steps on ROTN only, so these files would not decode; sizes are real).
- ``deadzone`` (theta): SH-band values round towards the channel mean with offset theta
  instead of 1/2 (k = sign(d) floor(|d| / q + theta)), a decoder-side no-op.

``ratio_vs_presets`` is the row's bytes over what the reference curve needs for its PSNR
(log-size linear in PSNR; null outside the curve): below 1 the rule pays.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402
from derived_steps import HeldOut, size_at_psnr  # noqa: E402

import csgs_codec.attributes.float_stream as float_stream  # noqa: E402
import csgs_codec.attributes.sh_colour_transform as colour_transform  # noqa: E402
import csgs_codec.codec.encoder as encoder_module  # noqa: E402
from csgs_codec.attributes import derived_steps  # noqa: E402
from csgs_codec.decisions.presets import preset_steps  # noqa: E402
from csgs_codec.entropy.residual import STEP_COUNT, step_size  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402

REST = ("rest1", "rest2", "rest3")
#: The rule in force: {"scored": strength or None, "theta": rounding offset or None}.
RULE: dict = {"scored": None, "theta": None, "rest_stream": False}


def footprint_classes(log_scales, opacity, base: int):
    """Scored steps for an SH band: 8 quantile bins of u, offsets from mean e^u (docstring)."""
    strength = RULE["scored"]
    weights = np.array([(1.0, 1.0, 0.0, 2.0), (0.0, 0.0, 0.0, 0.0)], np.float32)
    features = derived_steps.score_features(log_scales, opacity)
    u = derived_steps.score(features, weights[0])
    edges = np.unique(np.quantile(u, np.linspace(0, 1, 9)[1:-1]).astype(np.float32))
    thresholds_u, thresholds_v = edges[np.isfinite(edges)], np.zeros(0, np.float32)
    classes = derived_steps.derive_scored_classes(log_scales, opacity, weights, thresholds_u,
                                                  thresholds_v)
    k = len(thresholds_u) + 1
    count = np.bincount(classes, minlength=k).astype(np.float64)
    top = np.full(k, -np.inf)
    np.maximum.at(top, classes, u)
    top = np.where(np.isfinite(top), top, 0.0)
    sums = np.bincount(classes, weights=np.exp(u - top[classes]), minlength=k)
    log_mean = (top + np.log(np.maximum(sums, 1e-300)) - np.log(np.maximum(count, 1)))
    log_m = -0.5 * strength * log_mean / np.log(2.0)
    present = count > 0
    log_m -= np.sum(count[present] * log_m[present]) / count.sum()
    offsets = np.where(present, np.clip(np.rint(8 * log_m), -12, 12), 0).astype(np.int64)
    offsets = np.clip(base + offsets, 0, STEP_COUNT - 1) - base
    if not np.any(offsets[present]):
        return None
    return derived_steps.ScoredSteps(weights, thresholds_u, thresholds_v, offsets, classes)


_plain_quantize = float_stream.quantize
_plain_plan = float_stream.plan_float_stream


def deadzone_quantize(values, mean, step_idx):
    """float_stream's quantizer with rounding offset theta on SH-band streams."""
    if RULE["theta"] is None or not RULE["rest_stream"]:
        return _plain_quantize(values, mean, step_idx)
    d = np.asarray(values, np.int64) - np.asarray(mean, np.int64)
    q = step_size(np.asarray(step_idx, np.int64))
    offset = int(round(RULE["theta"] * 64))
    return np.sign(d) * ((64 * np.abs(d) + offset * q) // (64 * q))


def plan(values, step, derive=None, lattice=None):
    """plan_float_stream, telling the quantizer whether this is an SH band (9/15/21 wide)."""
    RULE["rest_stream"] = values.shape[1] in (9, 15, 21)
    try:
        return _plain_plan(values, step, derive, lattice)
    finally:
        RULE["rest_stream"] = False


def plan_color(self, values, p, lattices=None):
    """Encoder._plan_color with opacity and scales planned first, so the SH bands can take
    scored steps from their decoded values."""
    steps = preset_steps(p)
    lattices = lattices or {}
    plans = {}
    for name in ["opacity", "scale", *[n for n in values if n not in ("opacity", "scale")]]:
        if name not in values:
            continue
        derive = None
        if name == "rot" and name not in lattices:
            derive = self._rotation_classes(plans)
        elif name in REST and RULE["scored"] and not lattices:
            scales, opacity = plans["scale"].recon, plans["opacity"].recon
            derive = lambda base, s=scales, o=opacity: footprint_classes(s, o, base)  # noqa
            self._rest_derive[name] = derive
        plans[name] = plan(values[name], steps[name], derive, lattices.get(name))
    return {name: plans[name] for name in values}


def choose_transforms(plans, values, steps):
    """sh_colour_transform.choose_transforms, the opponent plan with the band's rule too."""
    transforms, chosen = [], {}
    band = 1
    while f"rest{band}" in plans:
        name = f"rest{band}"
        derive = getattr(RULE.get("encoder"), "_rest_derive", {}).get(name)
        turned = plan(colour_transform.forward(values[name]), steps[name], derive)
        better = colour_transform._bits(turned) < colour_transform._bits(plans[name])
        transforms.append(colour_transform.OPPONENT if better else colour_transform.IDENTITY)
        if better:
            chosen[name] = turned
        band += 1
    return tuple(transforms), chosen


def encode_row(scene, held: HeldOut, quality: int) -> dict:
    """One default encode at ``quality`` under the rule in force, scored."""
    encoder = encoder_module.Encoder(quality=quality)
    encoder._rest_derive = {}
    RULE["encoder"] = encoder
    result = encoder.encode_with_report(scene)
    return {"quality": quality, "bytes": len(result.data),
            "sh_band_bytes": sum(v for k, v in result.stream_bytes.items()
                                 if k.startswith("SHB")),
            "held_out_fg_psnr_db": held.psnr(result.reconstruction)}


def main() -> int:
    """Parse arguments, encode the reference curve and each rule, write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--qualities", type=int, nargs="+", default=[3, 5, 7])
    parser.add_argument("--strengths", type=float, nargs="*", default=[0.5, 1.0])
    parser.add_argument("--thetas", type=float, nargs="*", default=[0.4, 0.3])
    parser.add_argument("--size", default="400x300")
    parser.add_argument("--out")
    args = parser.parse_args()
    encoder_module.Encoder._plan_color = plan_color
    encoder_module.choose_transforms = choose_transforms
    float_stream.quantize = deadzone_quantize
    width, height = (int(v) for v in args.size.split("x"))
    scene = read_ply(args.scene)
    held = HeldOut(scene, width, height)
    name = Path(args.scene).name
    rows = []
    for quality in range(2, 9):
        rows.append({"scene": name, "rule": "default", **encode_row(scene, held, quality)})
        print(rows[-1], file=sys.stderr, flush=True)
    curve = [(r["held_out_fg_psnr_db"], r["bytes"]) for r in rows]
    variants = ([("scored", {"scored": s, "theta": None}) for s in args.strengths]
                + [("deadzone", {"scored": None, "theta": t}) for t in args.thetas])
    for rule, setting in variants:
        RULE.update(setting)
        for quality in args.qualities:
            row = {"scene": name, "rule": rule, "strength": setting["scored"],
                   "theta": setting["theta"], **encode_row(scene, held, quality)}
            needed = size_at_psnr(curve, row["held_out_fg_psnr_db"])
            row["ratio_vs_presets"] = None if np.isnan(needed) else row["bytes"] / needed
            rows.append(row)
            print(row, file=sys.stderr, flush=True)
    RULE.update({"scored": None, "theta": None})
    emit(document("sh_rest_rules", rows, settings=vars(args),
                  held_out_views=f"16 @20deg + 12 @45deg, {args.size}"), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
