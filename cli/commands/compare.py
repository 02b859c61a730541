"""``csgs compare REFERENCE CANDIDATE``: render PSNR, SSIM, foreground PSNR; attribute errors."""

from __future__ import annotations

import json
import math

NAME = "compare"
HELP = ("score a candidate scene against a reference: per-view and mean PSNR, SSIM and "
        "foreground PSNR of renders (black background), plus per-attribute errors")


def add_arguments(parser) -> None:
    """Arguments of ``csgs compare``."""
    from csgs_cli.view_options import add_view_arguments

    parser.add_argument("reference", help="the original scene (.ply)")
    parser.add_argument("candidate", help="the scene to score, e.g. a decoded one (.ply)")
    add_view_arguments(parser)
    parser.add_argument("--no-attributes", action="store_true",
                        help="skip the per-attribute errors (render scores only)")
    parser.add_argument("--json", action="store_true",
                        help="print JSON; an infinite PSNR (identical renders) is written as "
                             "the string \"inf\", an undefined one as null")


def run(args) -> int:
    """Compare the two scenes and print the report."""
    from csgs_cli.scene_input import load_scene
    from csgs_cli.view_options import cameras_from_args, progress
    from csgs_codec.metrics.comparison import compare_scenes

    reference = load_scene(args.reference, command=NAME)
    candidate = load_scene(args.candidate, command=NAME)
    from csgs_codec.model.anchor_views import SceneViews

    cameras = cameras_from_args(args, SceneViews(reference).framing())
    report = compare_scenes(reference, candidate, cameras, attributes=not args.no_attributes,
                            backend=args.backend,
                            progress=lambda views: progress(args, views, "comparing"))
    facts = report.to_dict()
    facts.update(reference=args.reference, candidate=args.candidate,
                 size=[cameras[0].width, cameras[0].height],
                 cameras=args.cameras or f"orbit of {len(cameras)} views")
    if args.json:
        print(json.dumps(json_safe(facts), indent=2, allow_nan=False))
    else:
        print(format_report(facts))
    return 0


def json_safe(value):
    """``value`` with inf as the string "inf" / "-inf" and nan as None (JSON has neither)."""
    if isinstance(value, float):
        if math.isnan(value):
            return None
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return value
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def _db(value: float) -> str:
    if math.isnan(value):
        return "-"
    return "inf" if math.isinf(value) else f"{value:.2f}"


def format_report(facts: dict) -> str:
    """Human-readable text for a comparison report."""
    lines = [f"{facts['candidate']} against {facts['reference']}: {facts['cameras']}, "
             f"{facts['size'][0]}x{facts['size'][1]}, black background",
             f"  {'view':<24} {'PSNR dB':>8} {'SSIM':>8} {'fg PSNR':>8} {'fg %':>6}"]
    for v in facts["views"]:
        lines.append(f"  {v['name'][:24]:<24} {_db(v['psnr']):>8} {v['ssim']:>8.5f} "
                     f"{_db(v['foreground_psnr']):>8} {100 * v['foreground_fraction']:>6.1f}")
    mean = facts["mean"]
    lines.append(f"  {'mean':<24} {_db(mean['psnr']):>8} {mean['ssim']:>8.5f} "
                 f"{_db(mean['foreground_psnr']):>8}")
    lines.append(f"  headline: foreground PSNR {_db(mean['foreground_psnr'])} dB "
                 "(pixels where the reference render's opacity > 0.05)")
    if facts["attribute_errors"] is not None:
        matching = facts["matching"]
        lines.append(f"  attribute errors (Gaussians matched by {matching['method']}"
                     + (f", max distance {matching['max_distance']:.3g}, "
                        f"{matching['unpicked_candidates']} candidates unpaired"
                        if matching["method"] == "nearest neighbour" else "") + "):")
        lines.append(f"    {'attribute':<12} {'max abs':>12} {'mean abs':>12}")
        for name, err in facts["attribute_errors"].items():
            lines.append(f"    {name:<12} {err['max_abs']:>12.6g} {err['mean_abs']:>12.6g}")
    lines.extend(f"  note: {note}" for note in facts["notes"])
    return "\n".join(lines)
