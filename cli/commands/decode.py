"""``csgs decode SCENE.csgs -o OUT.ply|.splat|.spz|.glb [--layers color|color,semantic]
[--region BOX | --tiles LIST]``."""

from __future__ import annotations

import time
from dataclasses import replace

NAME = "decode"
HELP = ("decode a .csgs bitstream into a 3DGS .ply, an antimatter15 .splat, a Niantic .spz "
        "(v4) or a glTF .glb (KHR_gaussian_splatting), picked by the output's extension")


def add_arguments(parser) -> None:
    """Arguments of ``csgs decode``."""
    parser.add_argument("bitstream", help="input .csgs")
    parser.add_argument("-o", "--output", required=True,
                        help="output .ply, .splat, .spz or .glb, picked by extension; an "
                             "anchor scene is baked into standard Gaussians for these, and "
                             "written as a Scaffold-GS checkpoint folder for any other name")
    parser.add_argument("--layers", default="color", type=layers_option,
                        metavar="color|color,semantic",
                        help="layers to decode, comma-separated in any order (default color; "
                             "'color' never reads the semantic bytes)")
    parser.add_argument("--region", type=region_option, default=None,
                        metavar="XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
                        help="decode only the spatial tiles whose box meets this box (whole "
                             "tiles; reads only their chunks); --region -1,... and "
                             "--region=-1,... both work")
    parser.add_argument("--tiles", type=tiles_option, default=None, metavar="LIST",
                        help="decode only these tiles, e.g. 0,3,5")
    parser.add_argument("--lod", type=int, default=None, metavar="K",
                        help="a file with levels of detail (csgs encode --levels): decode "
                             "level K, 0 (default: the scene itself) to the coarsest; with "
                             "--region, its tiles meeting the box")
    anchors = parser.add_argument_group("anchor scenes")
    anchors.add_argument("--sh-degree", type=int, default=None, choices=(0, 1, 2, 3),
                         help="SH degree of the baked colour (default 3)")
    anchors.add_argument("--cameras", metavar="FILE",
                         help="bake over these cameras' centres (cameras.json, transforms.json, "
                              "COLMAP, LLFF) instead of the training views the file stores")
    anchors.add_argument("--refine-bake", type=int, default=None, metavar="N",
                         help="Adam steps fitting the bake to the anchors' exact renders from "
                              f"the view origins (default {DEFAULT_REFINE_STEPS}; 0 gives the "
                              "browser page's bake, faster and about 0.6 dB lower on a real "
                              "capture)")
    anchors.add_argument("--checkpoint", metavar="DIR",
                         help="also write the decoded anchors as a Scaffold-GS checkpoint "
                              "folder")


#: Refinement steps of a bake ``csgs decode`` writes (16 s for mary_rose's 4,542 Gaussians).
DEFAULT_REFINE_STEPS = 300


def region_option(text: str) -> tuple[float, ...]:
    """The ``--region`` value as 6 floats (argparse type: a bad value exits 2)."""
    import argparse

    from csgs_codec.codec.decoder import check_region
    from csgs_codec.errors import InputError

    try:
        return check_region([float(v) for v in text.split(",")])
    except (ValueError, InputError) as err:
        message = getattr(err, "message", None) or (
            f"{text!r} is not 6 comma-separated numbers xmin,ymin,zmin,xmax,ymax,zmax")
        raise argparse.ArgumentTypeError(message) from None


def tiles_option(text: str) -> list[int]:
    """The ``--tiles`` value as tile numbers (argparse type: a bad value exits 2)."""
    import argparse

    parts = [p.strip() for p in text.split(",")]
    if not all(p.isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of tile "
                                         "numbers >= 0, e.g. 0,3,5")
    return [int(p) for p in parts]


def layers_option(text: str) -> str:
    """The ``--layers`` value normalised to "color" or "color,semantic" (argparse type)."""
    import argparse

    from csgs_codec.codec.container_access import parse_layers
    from csgs_codec.errors import InputError

    try:
        names = parse_layers(text)
    except InputError as err:
        raise argparse.ArgumentTypeError(err.message) from None
    return "color,semantic" if "semantic" in names else "color"


def run(args) -> int:
    """Decode the layers (and tiles) asked for and write the output atomically, in the format
    its extension names."""
    from tqdm import tqdm

    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_codec.atomic_write import check_output
    from csgs_codec.codec.anchor_decoder import is_anchor_file
    from csgs_codec.codec.decoder import Decoder
    from csgs_codec.errors import InputError
    from csgs_codec.interchange.writers import write_scene, writer_for

    if is_anchor_file(args.bitstream):
        if args.region is not None or args.tiles is not None or args.lod is not None:
            raise InputError("--region, --tiles and --lod apply to 3DGS scenes, not anchor "
                             "scenes",
                             file=args.bitstream)
        return _decode_anchors(args)
    for option in ("sh_degree", "cameras", "checkpoint", "refine_bake"):
        if getattr(args, option) is not None:
            raise InputError(f"--{option.replace('_', '-')} applies to anchor scenes; this "
                             "file holds standard Gaussians", file=args.bitstream,
                             property=f"--{option.replace('_', '-')}")
    refuse_overwriting_inputs([("-o", args.output)], [("the scene", args.bitstream)])
    check_output(args.output, [args.bitstream])
    writer_for(args.output)  # an unknown extension fails before the decode
    start = time.perf_counter()
    bar = []

    def progress(done: int, total: int) -> None:
        if not bar:
            bar.append(tqdm(total=total, desc="decode tiles", unit="tile", disable=args.quiet,
                            leave=False))
        bar[0].update(done - bar[0].n)

    try:
        report = Decoder().decode_with_report(args.bitstream, layers=args.layers,
                                              tiles=args.tiles, region=args.region,
                                              lod=args.lod, progress=progress)
    finally:
        if bar:
            bar[0].close()
    seconds = time.perf_counter() - start
    scene = report.scene
    if scene is None:
        raise InputError("no tile meets the region (nothing to decode)", property="region",
                         file=args.bitstream)
    write_scene(scene, args.output, [args.bitstream])
    note_semantic_left_out(args)
    extra = ""
    if scene.semantic is not None:
        extra += f", {scene.semantic.shape[1]} semantic channels"
    if scene.labels is not None:
        extra += ", labels"
    print(f"{args.output}: {len(scene):,} Gaussians, SH degree {scene.sh_degree_stored}"
          f"{extra} (decoded in {seconds:.2f} s)")
    share = 100.0 * report.bytes_read / max(report.file_bytes, 1)
    level = (f"level {report.level} of {report.levels}, " if report.levels > 1
             and report.level is not None else "")
    print(f"{level}tiles {_tile_list(report.tiles)} of {report.tile_count}; read "
          f"{report.bytes_read:,} of {report.file_bytes:,} bytes ({share:.1f}%)")
    return 0


def note_semantic_left_out(args) -> None:
    """Warn (a CsgsWarning: one stderr line, hidden by --quiet) when the file has a semantic
    layer that ``--layers`` left out, and say how to decode it."""
    import warnings

    from csgs_codec.errors import CsgsWarning

    if "semantic" in args.layers.split(",") or not has_semantic_layer(args.bitstream):
        return
    from pathlib import Path

    if Path(args.output).suffix.lower() in (".spz", ".splat", ".glb"):
        return  # these formats carry no semantic channels either way
    warnings.warn(CsgsWarning(f"{args.bitstream} has a semantic layer, not decoded (the "
                              "default is --layers color); add --layers color,semantic to "
                              "decode it"), stacklevel=2)


def has_semantic_layer(path: str) -> bool:
    """Whether the .csgs file at ``path`` holds semantic-layer data (a critical chunk of
    that layer), from its header and table of contents alone."""
    from csgs_codec.format import Layer
    from csgs_codec.format.source import open_source
    from csgs_codec.format.toc import read_toc

    source = open_source(path)
    try:
        entries = read_toc(source).entries
    finally:
        source.close()
    return any(e.layer == Layer.SEMANTIC and e.critical for e in entries)


def _tile_list(numbers: list[int]) -> str:
    """``0-3,5`` for [0, 1, 2, 3, 5]."""
    parts, start = [], None
    for i, n in enumerate(numbers):
        start = n if start is None else start
        if i + 1 == len(numbers) or numbers[i + 1] != n + 1:
            parts.append(str(n) if n == start else f"{start}-{n}")
            start = None
    return ",".join(parts) or "none"


def _decode_anchors(args) -> int:
    """Decode an anchor-scene bitstream: baked into a standard scene for an output with a
    scene-file extension, a Scaffold-GS checkpoint folder for any other name (and also at
    ``--checkpoint``)."""
    from pathlib import Path

    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_codec.atomic_write import check_output
    from csgs_codec.codec.anchor_decoder import AnchorDecoder
    from csgs_codec.interchange.scaffold_io import write_scaffold
    from csgs_codec.interchange.writers import WRITERS, write_scene

    bake = Path(args.output).suffix.lower() in WRITERS
    refuse_overwriting_inputs([("-o", args.output if bake else None)],
                              [("the scene", args.bitstream), ("--cameras", args.cameras)])
    if bake:
        check_output(args.output, [args.bitstream])
    start = time.perf_counter()
    scene = AnchorDecoder().decode(args.bitstream, layers=args.layers)
    seconds = time.perf_counter() - start
    note_semantic_left_out(args)
    if args.checkpoint or not bake:
        folder = args.checkpoint or args.output
        write_scaffold(scene, folder)
        print(f"{folder}: {len(scene):,} anchors (Scaffold-GS checkpoint folder; decoded in "
              f"{seconds:.2f} s)")
    if bake:
        baked, origin = bake_for_output(scene, args)
        write_scene(baked, args.output, [args.bitstream])
        print(f"{args.output}: {len(baked):,} Gaussians baked from {len(scene):,} anchors "
              f"({scene.active_offsets():,} slots), SH degree {baked.sh_degree_stored}, over "
              f"{origin} (decoded and baked in {time.perf_counter() - start:.2f} s)")
    return 0


def bake_for_output(scene, args):
    """(baked GaussianScene, where its view origins came from) for ``csgs decode``: the bake,
    then its refinement against the exact renders (a progress bar each)."""
    from tqdm import tqdm

    from csgs_codec.bake.anchor_bake import BakeSettings, bake_anchor_scene, bake_view_origins
    from csgs_codec.bake.refine import refine_bake
    from csgs_codec.scene.cameras_io import load_cameras

    steps = DEFAULT_REFINE_STEPS if args.refine_bake is None else args.refine_bake
    settings = BakeSettings(sh_degree=3 if args.sh_degree is None else args.sh_degree,
                            refine_steps=steps)
    settings.check()  # a bad --refine-bake exits 2 before the bake
    cameras = None
    if args.cameras:
        cameras = load_cameras(args.cameras)
        origin = f"{len(cameras)} cameras of {args.cameras}"
    elif scene.view_origins is not None:
        origin = f"the file's {len(scene.view_origins)} training view origins"
    else:
        origin = (f"{settings.directions * len(settings.distances)} views on a sphere (the "
                  "file stores no training views; --cameras gives them)")
    with tqdm(total=len(scene), desc="bake", unit="anchor", disable=args.quiet,
              leave=False) as bar:
        baked = bake_anchor_scene(scene, cameras=cameras, settings=replace(settings,
                                                                           refine_steps=0),
                                  progress=lambda done, total: bar.update(done - bar.n))
    if steps:
        origins = bake_view_origins(scene, cameras=cameras, settings=settings)
        with tqdm(total=steps, desc="refine the bake", unit="step", disable=args.quiet,
                  leave=False) as bar:
            baked = refine_bake(baked, scene, origins, steps=steps, size=settings.refine_size,
                                progress=lambda done, total: bar.update(done - bar.n))
        origin += f", refined in {steps} steps"
    return baked, origin
