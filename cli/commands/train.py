"""``csgs train DATA -o scene.csgs``: train a scene from images, cameras and masks (the three
CSGaussian stages) and write it as a .csgs with color and semantic layers."""

from __future__ import annotations

import math
from pathlib import Path

from csgs_codec.errors import InputError

NAME = "train"
#: The option that sets each stage-1 setting whose name differs from it.
OPTION_OF_SETTING = {"rate_weight": "lambda", "initial_anchors": "anchors",
                     "feat_dim": "features", "n_offsets": "offsets"}
#: Largest step, anchor and checkpoint counts (a larger one is a typo: 10^7 steps take weeks).
MAX_COUNT = 10_000_000
HELP = ("train a scene from images + cameras (+ instance masks) through the three CSGaussian "
        "stages and write it as a .csgs")


def add_arguments(parser) -> None:
    """Arguments of ``csgs train``."""
    from csgs_cli.dataset_input import add_builtin_segmenter_argument, add_outside_paths_argument
    from csgs_codec.train import defaults
    from csgs_codec.train.defaults import RATE_WEIGHT_PRESETS
    parser.add_argument("data", help="dataset: a folder with transforms.json, cameras.json "
                                     "(+ images/), a COLMAP model or an LLFF poses_bounds.npy "
                                     "(+ images/), or the camera file itself")
    parser.add_argument("-o", "--output", required=True, metavar="CSGS",
                        help="output .csgs file")
    parser.add_argument("--lambda", dest="rate_weight", type=float,
                        default=RATE_WEIGHT_PRESETS[0], metavar="L",
                        help="stage-1 rate weight lambda_rate (paper presets "
                             f"{', '.join(str(v) for v in RATE_WEIGHT_PRESETS)}; larger: "
                             f"smaller files; default {RATE_WEIGHT_PRESETS[0]})")
    parser.add_argument("--iterations", type=int, default=defaults.ITERATIONS, metavar="N",
                        help=f"stage-1 steps, one view each (default {defaults.ITERATIONS})")
    parser.add_argument("--budget", metavar="TIME", type=parse_duration,
                        help="finish in about this wall time (e.g. 10m, 90s, 1h): stage 1's "
                             "steps are set from the speed of its first 40 (instead of "
                             "--iterations; the file then depends on the machine's speed)")
    parser.add_argument("--semantic-iterations", type=int, default=defaults.SEMANTIC_ITERATIONS,
                        metavar="N", help="stage-2 steps (stage 3 runs two thirds as many; "
                                          f"default {defaults.SEMANTIC_ITERATIONS})")
    parser.add_argument("--semantic-margin", type=float,
                        default=defaults.CONTRASTIVE_MARGIN, metavar="M",
                        help="contrastive margin between masks' mean features, in quantization "
                             "steps (smaller: a smaller semantic layer, masks less apart; "
                             f"default {defaults.CONTRASTIVE_MARGIN:g})")
    parser.add_argument("--semantic-rate", type=float,
                        default=defaults.FEATURE_RATE_WEIGHT, metavar="W",
                        help="stage-3 weight of the semantic features' estimated bits "
                             f"(default {defaults.FEATURE_RATE_WEIGHT:g})")
    parser.add_argument("--resolution", type=int, metavar="R",
                        help="downscale images so their longer side is at most R pixels")
    parser.add_argument("--quality", type=int, default=defaults.QUALITY, choices=range(1, 10),
                        metavar="Q", help="encoder quality 1..9 whose quantization steps "
                                          f"training simulates (default {defaults.QUALITY})")
    parser.add_argument("--anchors", type=int, default=defaults.INITIAL_ANCHORS, metavar="M",
                        help="initial anchors (about; default "
                             f"{defaults.INITIAL_ANCHORS}); growth may add up to "
                             f"--max-anchors")
    parser.add_argument("--max-anchors", type=int, default=defaults.MAX_ANCHORS, metavar="M",
                        help=f"anchor limit of growth (default {defaults.MAX_ANCHORS})")
    parser.add_argument("--features", type=int, default=defaults.FEAT_DIM, metavar="F",
                        help=f"anchor feature width (default {defaults.FEAT_DIM})")
    parser.add_argument("--offsets", type=int, default=defaults.N_OFFSETS, metavar="K",
                        help=f"Gaussians per anchor (default {defaults.N_OFFSETS})")
    parser.add_argument("--points", metavar="PLY",
                        help="initial point cloud (default: the dataset's, else random)")
    parser.add_argument("--masks", metavar="DIR",
                        help="instance-mask folder (default: masks/ beside the images; "
                             "without one a built-in segmenter makes masks, with a warning; "
                             "docs/masks.md)")
    add_builtin_segmenter_argument(parser)
    add_outside_paths_argument(parser)
    parser.add_argument("--foreground-masks", metavar="DIR",
                        help="folder of object masks (255 object, 0 background; one per "
                             "image, named by its stem): train the object alone with a "
                             "transparent background (default: the capture's masks/ folder "
                             "when it holds only 0/255 masks)")
    parser.add_argument("--no-foreground-masks", action="store_true",
                        help="train whole photos even when the capture has 0/255 masks "
                             "(masks/ is then read as instance masks)")
    parser.add_argument("--no-semantic", action="store_true",
                        help="train color only (no masks, no semantic layer)")
    parser.add_argument("--test-every", type=int, default=8, metavar="K",
                        help="hold out every K-th view to score the result (0: none; "
                             "default 8)")
    parser.add_argument("--checkpoint-dir", metavar="DIR",
                        help="save stage-1 checkpoints here (every --checkpoint-every steps)")
    parser.add_argument("--checkpoint-every", type=int, default=500, metavar="N",
                        help="steps between checkpoints (default 500)")
    parser.add_argument("--resume", action="store_true",
                        help="continue from the checkpoint in --checkpoint-dir")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"),
                        help="torch device to train on (default cpu)")
    parser.add_argument("--rasterizer", default="auto", choices=("auto", "torch", "gsplat"),
                        help="differentiable rasterizer for stage 1 (default auto: gsplat's "
                             "CUDA kernels with --device cuda when gsplat is installed, else "
                             "the torch reference)")
    parser.add_argument("--threads", type=int, default=defaults.THREADS, metavar="N",
                        help="torch CPU threads (default 1: the same file on every machine; "
                             "more can be faster for large scenes on a quiet machine)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


#: Shortest and longest --budget, seconds.
BUDGET_RANGE = (10.0, 7 * 24 * 3600.0)


def parse_duration(text: str) -> float:
    """Seconds of a duration written ``90``, ``90s``, ``10m`` or ``1.5h``."""
    import argparse

    units = {"s": 1.0, "m": 60.0, "h": 3600.0}
    number, unit = (text[:-1], text[-1]) if text[-1:].lower() in units else (text, "s")
    try:
        seconds = float(number) * units[unit.lower()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a duration such as 90s, 10m or "
                                         "1h") from None
    if not BUDGET_RANGE[0] <= seconds <= BUDGET_RANGE[1]:
        raise argparse.ArgumentTypeError(f"{text!r}: a budget must be 10 s to 7 days")
    return seconds


def run(args) -> int:
    """Load the dataset, train every stage, write the .csgs atomically and print a summary."""
    import time

    started = time.perf_counter()
    import torch
    from tqdm import tqdm

    from csgs_cli.dataset_input import check_output_folder, downscale_for, mask_fallback
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_codec.atomic_write import write_atomically
    from csgs_codec.codec.describe import describe_bitstream
    from csgs_codec.render.differentiable import resolve_training_rasterizer
    from csgs_codec.train.color_stage import ColorStageSettings
    from csgs_codec.train.datasets import dataset_files, find_foreground_masks, load_dataset
    from csgs_codec.train.evaluation import score_views, split_views
    from csgs_codec.train.initial_points import find_initial_points
    from csgs_codec.train.pipeline import TrainSettings, train_scene
    from csgs_codec.train.segment import MAX_MARGIN

    if args.device == "cuda" and not torch.cuda.is_available():
        raise InputError("--device cuda: torch sees no CUDA device", property="device")
    if not (math.isfinite(args.rate_weight) and args.rate_weight >= 0):
        raise InputError(f"--lambda must be a finite number >= 0, got {args.rate_weight}",
                         property="lambda")
    if args.budget is not None and args.resume:
        raise InputError("--budget plans a run from its start: resume without it",
                         property="budget")
    for name in ("iterations", "semantic_iterations", "anchors", "max_anchors",
                 "checkpoint_every"):
        if not 1 <= getattr(args, name) <= MAX_COUNT:
            raise InputError(f"--{name.replace('_', '-')} must be 1..{MAX_COUNT:,}",
                             property=name)
    if not (math.isfinite(args.semantic_margin) and 0 < args.semantic_margin <= MAX_MARGIN):
        raise InputError(f"--semantic-margin must be a number in (0, {MAX_MARGIN:g}], got "
                         f"{args.semantic_margin}", property="semantic-margin")
    if not (math.isfinite(args.semantic_rate) and args.semantic_rate >= 0):
        raise InputError(f"--semantic-rate must be a finite number >= 0, got "
                         f"{args.semantic_rate}", property="semantic-rate")
    if args.resume and not args.checkpoint_dir:
        raise InputError("--resume needs --checkpoint-dir", property="resume")
    if args.max_anchors < args.anchors:
        raise InputError(f"--max-anchors {args.max_anchors} is below --anchors "
                         f"{args.anchors}", property="max-anchors")
    if args.test_every == 1:
        raise InputError("--test-every 1 would hold out every view, leaving none to train "
                         "on", property="test-every")
    color = ColorStageSettings(
        iterations=args.iterations, rate_weight=args.rate_weight, quality=args.quality,
        initial_anchors=args.anchors, max_anchors=args.max_anchors, feat_dim=args.features,
        n_offsets=args.offsets, seed=args.seed, device=args.device, threads=args.threads,
        rasterizer=args.rasterizer)
    try:
        color.validate()
    except InputError as error:
        option = OPTION_OF_SETTING.get(error.property, error.property or "")
        raise InputError(error.message.replace(error.property or "", option),
                         property=f"--{option.replace('_', '-')}") from None
    if args.foreground_masks and args.no_foreground_masks:
        raise InputError("--foreground-masks and --no-foreground-masks contradict each other",
                         property="no-foreground-masks")
    resolve_training_rasterizer(args.rasterizer, args.device)  # fail before loading images
    check_output_folder(Path(args.output))
    foreground = args.foreground_masks
    outside = args.allow_outside_paths
    if foreground is None and not args.no_foreground_masks:
        foreground = find_foreground_masks(args.data, allow_outside_paths=outside)
    masks = None if args.no_semantic else args.masks
    refuse_overwriting_inputs(
        [("-o", args.output)],
        [("--points", args.points)]
        + [("the dataset", file)
           for file in dataset_files(args.data, masks=masks, foreground=foreground,
                                     allow_outside_paths=outside)])
    with mask_fallback(args):
        views = load_dataset(args.data, downscale=downscale_for(args.data, args.resolution),
                             masks=None if args.no_semantic else args.masks,
                             segment_missing=not args.no_semantic,
                             read_masks=not args.no_semantic, foreground=foreground,
                             allow_outside_paths=outside)
    train_views, test_views = split_views(views, args.test_every)
    points, source = find_initial_points(args.data, [v.camera for v in train_views],
                                         points=args.points, seed=args.seed,
                                         views=train_views)
    settings = TrainSettings(color, semantic_iterations=args.semantic_iterations,
                             stage3_iterations=max(1, 2 * args.semantic_iterations // 3),
                             feature_rate_weight=args.semantic_rate,
                             contrastive_margin=args.semantic_margin,
                             checkpoint_every=args.checkpoint_every)
    if not args.quiet:
        print(f"{len(train_views)} training views, {len(test_views)} held out, "
              f"{views[0].width}x{views[0].height}; initial points: {source}")
        if foreground is not None:
            how = ("given" if args.foreground_masks else
                   "found: 0/255 masks; --no-foreground-masks trains the whole photos")
            print(f"foreground masks: {foreground} ({how}); training the object alone, its "
                  "background transparent")
    bars = [tqdm(total=args.iterations, desc="stage 1", unit="step", disable=args.quiet,
                 leave=False)]
    stages = ["stage 1"]

    def progress(stage, step) -> None:
        bar = bars[-1]
        if step is None:  # a stage starts: stage 1 keeps its bar, later ones get their own
            if stage.startswith("stage 1") or stages[-1] == stage:
                bar.set_description(stage)
                return
            bar.close()
            stages.append(stage)
            bars.append(tqdm(total=None, desc=stage, unit="step", disable=args.quiet,
                             leave=False))
            return
        if bar.total != step.iterations:
            bar.reset(total=step.iterations)
        if not math.isnan(step.loss):
            bar.set_postfix(loss=f"{step.loss:.4f}", psnr=f"{step.psnr:.1f}",
                            bpp=f"{step.bits_per_parameter:.2f}", anchors=step.anchors,
                            refresh=False)
        bar.update(step.step - bar.n)

    if args.budget is not None:
        settings.budget_seconds = args.budget - (time.perf_counter() - started)
    try:
        result = train_scene(train_views, points, settings, checkpoint_dir=args.checkpoint_dir,
                             resume=args.resume, progress=progress)
    finally:
        bars[-1].close()
    write_atomically(args.output, result.data)
    scene = result.encode.reconstruction
    share = describe_bitstream(result.data)["semantic_share_percent"]  # as csgs info says
    print(f"{args.output}: {len(result.data):,} bytes, {len(scene):,} anchors, "
          f"{scene.active_offsets():,} Gaussian slots, semantic layer {share:.1f}% of the file")
    timings = ", ".join(f"{k} {v:.1f} s" for k, v in result.seconds.items())
    print(f"time: {timings}")
    if args.budget is not None:
        print(f"budget {args.budget:.0f} s: stage 1 ran {result.color_state.step:,} steps, the "
              f"run {time.perf_counter() - started:.0f} s")
    if test_views:
        scores = score_views(scene, test_views)
        inside = ("" if math.isnan(scores.foreground_psnr) else
                  f", PSNR inside the foreground masks {scores.foreground_psnr:.2f} dB")
        print(f"held-out views: PSNR {scores.psnr:.2f} dB, SSIM {scores.ssim:.4f}{inside} "
              f"({scores.views} views, decoded scene)")
    return 0
