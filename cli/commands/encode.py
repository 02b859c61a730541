"""``csgs encode SCENE.ply -o SCENE.csgs``: compress a 3DGS scene."""

from __future__ import annotations

import argparse
import os
from time import perf_counter

from tqdm import tqdm

from csgs_codec.decisions.presets import (
    DEFAULT_QUALITY,
    DEFAULT_ROTATION_STEPS,
    QUALITIES,
    ROTATION_STEPS,
)
from csgs_codec.errors import InputError

NAME = "encode"
HELP = ("compress a 3DGS scene (PLY, compressed PLY, .splat, .ksplat, SPZ, SOG, GLB) or a "
        "Scaffold-GS anchor scene into a .csgs bitstream")
STAGES = ("step allocation", "geometry", "color", "color hyperprior", "semantic", "container")
#: How a counted stage's bar reads (description, unit); others show the stage's name.
STEP_BARS = {"color hyperprior": ("color hyperprior fit", "step"), "view sensitivity":
             ("view sensitivity", "view"), "tiles": ("tiles", "tile"),
             "refinement": ("refinement", "step"), "step allocation": ("step allocation", "probe")}


def add_arguments(parser) -> None:
    """Arguments of ``csgs encode``."""
    parser.add_argument("scene", help="input scene (3DGS PLY, compressed PLY, .splat, .ksplat, "
                                      "SPZ, SOG .sog or folder, GLB; recognised by content), "
                                      "an INRIA output folder, or a Scaffold-GS checkpoint "
                                      "folder / anchor .ply (coded as an anchor scene)")
    parser.add_argument("-o", "--output", required=True, help="output .csgs file")
    parser.add_argument("--quality", type=int, default=None, choices=QUALITIES,
                        metavar="1-12", help=f"1 smallest .. 9 high; 10-12 near-lossless "
                                             f"(3DGS scenes; anchor scenes take 1-9) "
                                             f"(default {DEFAULT_QUALITY})")
    parser.add_argument("--target-psnr", type=float, default=None, metavar="DB",
                        help="instead of --quality: the smallest file whose renders reach this "
                             "foreground PSNR on the encoder's probe views (several encodes)")
    parser.add_argument("--lambda", dest="lambda_", type=float, default=None, metavar="L",
                        help="experts, instead of --quality/--target-psnr: the rate-distortion "
                             "weight. 3DGS scenes: minimise D + L*R on probe renders (D: "
                             "foreground MSE in squared 8-bit levels, R: bits per Gaussian; "
                             "0.25 is near quality 5). Anchor scenes: the fit's weight in "
                             "squared value units per bit (4e-4 is near quality 5)")
    parser.add_argument("--fast", action="store_true",
                        help="a faster encode for a slightly larger file (anchor scenes: a "
                             "short fit, 3-5x faster; 3DGS scenes: no color hyperprior fit "
                             "and shorter --target-psnr and --lambda searches)")
    parser.add_argument("--no-hyperprior", dest="hyperprior", action="store_false",
                        help="3DGS scenes: skip the color hyperprior fit (about 10 s on "
                             "scenes of 8,192+ Gaussians); the file is larger, the decoded "
                             "scene the same")
    parser.add_argument("--semantic", choices=("auto", "none"), default="auto",
                        help="write the semantic layer when the scene has semantic channels "
                             "(auto) or never (none)")
    parser.add_argument("--prune-opacity", type=float, default=None, metavar="T",
                        help="drop Gaussians with opacity below T (lossy, opt-in)")
    parser.add_argument("--view-prune", dest="view_pruning", default=None,
                        action=argparse.BooleanOptionalAction,
                        help="3DGS scenes: leave out the Gaussians that add least to renders "
                             "from the viewing distribution, within 10%% of the quantization's "
                             "own squared error on each probe view (lossy; a sphere of views "
                             "around the scene unless cameras are known). Default: on when "
                             "cameras are given (--cameras, or an INRIA output folder), else "
                             "off")
    parser.add_argument("--rotation-steps", choices=ROTATION_STEPS,
                        default=DEFAULT_ROTATION_STEPS,
                        help="3DGS scenes: how each Gaussian's rotation step follows its "
                             "decoded attributes, at no per-Gaussian cost: 'footprint' "
                             "(default) by its area, opacity and anisotropy, coarser where a "
                             "rotation barely shows; 'uniform' one step for all")
    parser.add_argument("--step-allocation", default=None,
                        action=argparse.BooleanOptionalAction,
                        help="3DGS scenes: move each attribute's step (DC, each SH band, "
                             "opacity, scales, rotations) and the position bits from the "
                             "quality preset's, per scene, where small probe renders say the "
                             "file gets smaller at equal quality (scenes of 1,024+ Gaussians "
                             "in one tile; not with --fast, --target-psnr or --lambda). "
                             "Default: on for scenes with SH bands (where it pays), off for "
                             "SH-0 scenes")
    parser.add_argument("--refine", type=int, default=0, metavar="N",
                        help="3DGS scenes: N steps that move each coded value to the lattice "
                             "point whose decoded scene renders closest to the original over "
                             "the viewing distribution (--cameras or the default sphere); same "
                             "format, lower render error at about the same size; seconds per "
                             "step on large scenes. Default 0")
    parser.add_argument("--cameras", default=None, metavar="FILE",
                        help="3DGS scenes: the views the scene will be seen from (INRIA "
                             "cameras.json, transforms.json or a COLMAP folder). Give them "
                             "for a scene walked through from inside")
    parser.add_argument("--sanitize", action="store_true",
                        help="drop Gaussians with NaN/Inf values instead of failing")
    parser.add_argument("--order-out", default=None, metavar="FILE.npy",
                        help="3DGS scenes: also write the decoded order as an int64 .npy: "
                             "entry i is the input Gaussian (row of the input file) that "
                             "decoded Gaussian i came from; pruned ones appear nowhere. "
                             "Per-Gaussian data x of the input lines up with the decoded "
                             "scene as x[order]. Not stored in the .csgs")
    parser.add_argument("--tile-size", type=int, default=None, metavar="N",
                        help="3DGS scenes: split into spatial tiles of at most N Gaussians, "
                             "each coded on its own (region decode reads only the tiles it "
                             "needs). Default: tiles of 1,000,000 for scenes of more than "
                             "2,000,000 Gaussians, else one tile (the file is then as without "
                             "tiles). At least 1,000 (a scene under 16,000 Gaussians: a 16th "
                             "of it), and at most 4,095 tiles")
    parser.add_argument("--levels", type=int, default=1, metavar="L",
                        help="3DGS scenes: levels of detail for streaming viewers (default 1: "
                             "none). L > 1 adds L - 1 coarser versions of the scene, each "
                             "about 1/8 of the one below, coded first, in tiles of --tile-size "
                             "(default 65,536); decoders give the scene itself unless asked "
                             "for a level (csgs decode --lod K)")
    parser.add_argument("--workers", type=int, default=1, metavar="N",
                        help="local processes coding tiles side by side (default 1); the "
                             "file is the same for any N")
    parser.add_argument("--ray", default=None, metavar="ADDRESS",
                        help="code the tiles on the Ray cluster at ADDRESS ('local' starts "
                             "one on this machine with --workers CPUs; needs pip install "
                             "ray); the file is the same as without it")


def run(args) -> int:
    """Read, encode and write atomically; print the sizes."""
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_cli.scene_input import inria_output, is_anchor_input
    from csgs_codec.atomic_write import check_output, write_atomically
    from csgs_codec.codec.encoder import COUNTED_STAGES, Encoder
    from csgs_codec.codec.encoder_config import EncoderConfig
    from csgs_codec.codec.files import read_scene_with_report
    from csgs_codec.interchange import warn_if_lossy

    _check_exclusive(args)
    refuse_overwriting_inputs([("-o", args.output), ("--order-out", args.order_out)],
                              [("the scene", args.scene), ("--cameras", args.cameras)])
    inria = inria_output(args.scene)
    # Before a long encode, not after it.
    check_output(args.output, [args.scene] + ([str(inria[0])] if inria else []))
    if args.order_out is not None:
        if args.sanitize:
            raise InputError("--order-out numbers the input file's rows, and --sanitize drops "
                             "rows before encoding: fix the NaN/Inf values or leave out "
                             "--order-out", property="--order-out")
        check_output(args.order_out, [args.scene])
    if is_anchor_input(args.scene):
        return _encode_anchors(args, write_atomically)
    scene_path, cameras_path = args.scene, args.cameras
    if inria is not None:  # an INRIA output folder: its latest point cloud, its cameras
        scene_path = str(inria[0])
        cameras_path = cameras_path or str(inria[1])
    cameras = None
    if cameras_path is not None:
        from csgs_codec.scene.cameras_io import load_cameras

        cameras = load_cameras(cameras_path)
    config = EncoderConfig(quality=args.quality, target_psnr=args.target_psnr,
                           lambda_=args.lambda_, fast=args.fast, semantic=args.semantic,
                           prune_opacity=args.prune_opacity, hyperprior=args.hyperprior,
                           view_pruning=args.view_pruning, cameras=cameras,
                           tile_size=args.tile_size,
                           rotation_steps=args.rotation_steps,
                           step_allocation=args.step_allocation, refine=args.refine,
                           workers=args.workers, ray=args.ray, levels=args.levels)
    searching = args.target_psnr is not None or args.lambda_ is not None
    view_pruning = config.prunes_views
    streamed = (not searching and not view_pruning and args.prune_opacity is None
                and not args.sanitize and not args.refine and args.levels == 1
                and _tiled_binary_ply(scene_path, args.tile_size))
    scene = None
    if not streamed:
        scene, source = read_scene_with_report(scene_path, sanitize=args.sanitize,
                                               layers="color,semantic")
        warn_if_lossy(source, scene_path)
    bar = tqdm(total=None if searching or view_pruning else len(STAGES), desc="encode",
               unit="stage",
               disable=args.quiet, leave=False)

    step_bars = {stage: _StepBar(*STEP_BARS.get(stage, (stage, "step")), args.quiet)
                 for stage in COUNTED_STAGES}

    def progress(stage: str, done: int, total: int) -> None:
        if total:
            step_bars[stage](done, total)
            return
        bar.set_postfix_str(stage)
        bar.update(1)

    encoder = Encoder(config, progress=progress)
    # Timed here: an encode streamed tile by tile reports no time of its own (issue #29).
    start = perf_counter()
    try:
        if scene is None:  # a tiled scene streamed from its memory-mapped body
            from csgs_codec.codec.tile_encoder import encode_ply_tiled

            result = encode_ply_tiled(encoder, scene_path)
        else:
            result = encoder.encode_with_report(scene)
    except InputError as err:  # the scene's errors (row, property) belong to the input file
        if err.file is None:
            err.file = scene_path
        raise
    finally:
        for step_bar in step_bars.values():
            step_bar.close()
        bar.close()
    seconds = perf_counter() - start
    write_atomically(args.output, result.data, [args.scene, scene_path])
    if args.order_out is not None:
        write_atomically(args.order_out, order_npy(result.order), [args.scene, scene_path])
    n = len(result.order)
    in_bytes = _input_bytes(scene_path)
    bits = 8 * len(result.data) / max(n, 1)
    print(f"{args.output}: {len(result.data):,} bytes, {n:,} Gaussians, {bits:.2f} bits/Gaussian"
          f", {in_bytes / max(len(result.data), 1):.1f}x smaller than the input, "
          f"{seconds:.2f} s")
    if result.levels > 1:
        print(f"{result.tiles} tiles in {result.levels} levels of detail")
    elif result.tiles > 1:
        print(f"{result.tiles} spatial tiles")
    if result.rate_control is not None:
        print(f"rate control: {result.rate_control.summary()}")
    if result.allocation is not None:
        print(f"step allocation: {result.allocation.summary()}")
    if result.pruned:
        print(f"pruned {result.pruned:,} Gaussians with opacity below {args.prune_opacity}")
    if result.views is not None:
        print(f"left out {result.view_pruned:,} Gaussians that add least to the views "
              f"({result.views})")
    return 0


def _encode_anchors(args, write_atomically) -> int:
    """Encode a Scaffold-GS anchor scene (checkpoint folder or anchor PLY)."""
    from csgs_cli.scene_input import load_anchor_scene
    from csgs_codec.codec.anchor_encoder import AnchorEncoder

    if (args.prune_opacity is not None or args.sanitize or args.target_psnr is not None
            or args.cameras is not None or args.view_pruning or args.tile_size is not None
            or args.levels != 1
            or args.workers != 1 or args.ray is not None
            or args.rotation_steps != DEFAULT_ROTATION_STEPS or args.refine
            or args.order_out is not None):
        raise InputError("--prune-opacity, --sanitize, --target-psnr, --cameras, "
                         "--view-prune, --tile-size, --levels, --workers, --ray, "
                         "--rotation-steps, "
                         "--refine and --order-out apply to 3DGS PLY input, not to "
                         "anchor scenes",
                         file=args.scene)
    encoder = AnchorEncoder(quality=args.quality, lambda_=args.lambda_, fast=args.fast,
                            semantic=args.semantic)
    scene = load_anchor_scene(args.scene)
    with tqdm(total=1, desc="encode anchors (fit + code)", disable=args.quiet, leave=False):
        result = encoder.encode_with_report(scene)
    write_atomically(args.output, result.data, [args.scene])
    m = len(result.reconstruction)
    print(f"{args.output}: {len(result.data):,} bytes, {m:,} anchors, "
          f"{8 * len(result.data) / max(m, 1):.1f} bits/anchor, {result.seconds:.2f} s "
          f"(fit {result.fit_seconds:.2f} s)")
    return 0


def order_npy(order) -> bytes:
    """The bytes of a .npy file holding ``order`` as (M,) little-endian int64 (no pickles)."""
    import io

    import numpy as np

    buffer = io.BytesIO()
    np.save(buffer, np.ascontiguousarray(order, dtype="<i8"), allow_pickle=False)
    return buffer.getvalue()


def _input_bytes(path: str) -> int:
    """Size of the input: a file, or the files of a folder (a SOG folder)."""
    if os.path.isdir(path):
        return sum(f.stat().st_size for f in os.scandir(path) if f.is_file())
    return os.path.getsize(path)


def _tiled_binary_ply(path: str, tile_size: int | None) -> bool:
    """True when ``path`` is a binary PLY the encoder will tile (more Gaussians than the tile
    size): it is then encoded tile by tile from its memory-mapped body, never loaded whole
    (the same bytes as a whole read)."""
    from csgs_codec.codec.tiling import effective_tile_size
    from csgs_codec.interchange.ply_mmap import MappedPly

    try:
        mapped = MappedPly(path)
    except InputError:
        return False  # not a binary PLY (or unusual): read whole, which reports any real error
    if not {"x", "y", "z"} <= set(mapped.properties):
        return False  # e.g. a PlayCanvas compressed PLY: its own reader decodes it
    count = mapped.count
    return count > effective_tile_size(count, tile_size)


def _check_exclusive(args) -> None:
    """InputError (exit 2) when --lambda comes with --quality or --target-psnr."""
    if args.lambda_ is not None and (args.quality is not None or args.target_psnr is not None):
        raise InputError("--lambda excludes --quality and --target-psnr: give one of them",
                         property="lambda")


class _StepBar:
    """A ``progress(done, total)`` callback that shows a tqdm bar while a run of steps goes
    on (the bar closes when ``done`` reaches ``total``; :meth:`close` closes one left open by
    an error)."""

    def __init__(self, description: str, unit: str, quiet: bool) -> None:
        self.description, self.unit, self.quiet = description, unit, quiet
        self.bar = None

    def __call__(self, done: int, total: int) -> None:
        if self.bar is None:
            self.bar = tqdm(total=total, desc=self.description, unit=self.unit,
                            disable=self.quiet, leave=False)
        self.bar.update(done - self.bar.n)
        if done == total:
            self.close()

    def close(self) -> None:
        """Close the bar if one is open."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None
