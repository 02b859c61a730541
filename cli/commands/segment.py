"""``csgs segment SCENE --images DATA [--cameras FILE] [--masks DIR] -o OUT.ply|OUT.csgs``: give
every Gaussian of a trained 3DGS scene an instance (semantic feature), from its capture's
cameras and instance masks, and write it as a PLY with ``ins_feat_*`` properties or as a
.csgs."""

from __future__ import annotations

from pathlib import Path

from csgs_codec.errors import InputError

NAME = "segment"
HELP = ("add semantic features (one instance per Gaussian) to a 3DGS scene from its "
        "capture's cameras and instance masks; write a .ply or a .csgs")
#: Images are brought down to this longest side unless --resolution says otherwise (the
#: per-view compositing lists grow with the pixels).
DEFAULT_RESOLUTION = 640


def add_arguments(parser) -> None:
    """Arguments of ``csgs segment``."""
    from csgs_cli.dataset_input import add_builtin_segmenter_argument, add_outside_paths_argument
    from csgs_codec.decisions.presets import DEFAULT_QUALITY, QUALITIES
    from csgs_codec.train import defaults

    parser.add_argument("scene", help="the trained scene: any 3DGS file 'csgs encode' reads, "
                                      "or a .csgs of a standard scene")
    parser.add_argument("--images", required=True, metavar="DATA",
                        help="the capture: a folder with transforms.json, cameras.json "
                             "(+ images/) or a COLMAP model, in the scene's world frame; "
                             "with --cameras, the folder of the images")
    parser.add_argument("--cameras", metavar="FILE",
                        help="the cameras of the images in --images (transforms.json, INRIA "
                             "cameras.json or a COLMAP model), each image found under the "
                             "name the file gives it, any image suffix: e.g. the views "
                             "'csgs render SCENE --cameras FILE -o DIR' wrote")
    parser.add_argument("--masks", metavar="DIR",
                        help="instance masks, one integer id image per view named after "
                             "its image (encodings, and SAM's per-object masks: "
                             "docs/masks.md, 'csgs combine-masks'); default: masks/ in or "
                             "beside the image folder, else the built-in segmenter (weaker, "
                             "with a warning)")
    add_builtin_segmenter_argument(parser)
    add_outside_paths_argument(parser)
    parser.add_argument("--mask-embeddings", metavar="DIR",
                        help="one .npy per view named after its image, row i an embedding "
                             "of mask id i (e.g. CLIP image embeddings of the masks): the "
                             ".csgs then answers 'csgs query'")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="output .ply (features as ins_feat_* properties) or .csgs")
    parser.add_argument("--iterations", type=int, default=defaults.SEMANTIC_ITERATIONS,
                        metavar="N", help="stage-2 steps (default "
                                          f"{defaults.SEMANTIC_ITERATIONS})")
    parser.add_argument("--margin", type=float, default=defaults.CONTRASTIVE_MARGIN,
                        metavar="M", help="contrastive margin between masks' features "
                                          f"(default {defaults.CONTRASTIVE_MARGIN:g})")
    parser.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION, metavar="R",
                        help="downscale views so their longer side is at most R pixels "
                             f"(default {DEFAULT_RESOLUTION})")
    parser.add_argument("--quality", type=int, default=DEFAULT_QUALITY, choices=QUALITIES,
                        metavar="Q", help="encoder quality for a .csgs output (default "
                                          f"{DEFAULT_QUALITY})")
    parser.add_argument("--ignore-id", type=int, metavar="ID",
                        help="mask id of pixels that belong to no object (e.g. 0 where the "
                             "masks mark unlabelled pixels 0); default: every id is an object")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"),
                        help="where to composite and train (default cpu)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def run(args) -> int:
    """Load the scene and the views, segment, write the output; print a summary."""
    import torch
    from tqdm import tqdm

    from csgs_cli.dataset_input import check_output_folder, downscale_for, mask_fallback
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_cli.scene_input import load_scene
    from csgs_codec.atomic_write import check_output, write_atomically
    from csgs_codec.interchange.ply_io import ply_bytes
    from csgs_codec.train.datasets import dataset_files, load_dataset
    from csgs_codec.train.segment import SegmentSettings, segment_scene

    output = Path(args.output)
    suffix = output.suffix.lower()
    if suffix not in (".ply", ".csgs"):
        raise InputError("the output must end in .ply or .csgs", file=output)
    if args.device == "cuda" and not torch.cuda.is_available():
        raise InputError("--device cuda: torch sees no CUDA device", property="device")
    settings = SegmentSettings(iterations=args.iterations, margin=args.margin, seed=args.seed,
                               device=args.device, ignore_id=args.ignore_id)
    try:
        settings.validate()
    except InputError as error:
        raise InputError(error.message, property=f"--{error.property}") from None
    check_output_folder(output)
    # With --cameras, --images is the folder the cameras' image names are relative to.
    data, images = (args.cameras, args.images) if args.cameras else (args.images, None)
    refuse_overwriting_inputs(
        [("-o", output)],
        [("the scene", args.scene), ("--mask-embeddings", args.mask_embeddings),
         ("--cameras", args.cameras)]
        + [("--images", file) for file in dataset_files(
            data, masks=args.masks, images=images,
            allow_outside_paths=args.allow_outside_paths)])
    check_output(output, [args.scene])
    scene = load_scene(args.scene, command=NAME, layers="color")
    with mask_fallback(args):
        views = load_dataset(data, downscale=downscale_for(data, args.resolution),
                             masks=args.masks, images=images, segment_missing=True,
                             allow_outside_paths=args.allow_outside_paths)
    embeddings = None
    if args.mask_embeddings:
        if suffix != ".csgs":
            raise InputError("instance embeddings travel in a .csgs only; name a .csgs output",
                             file=output)
        embeddings = read_mask_embeddings(Path(args.mask_embeddings), views)
    if not args.quiet:
        print(f"{len(scene):,} Gaussians, {len(views)} views at "
              f"{views[0].width}x{views[0].height}")
    bars = {}

    def progress(phase: str, done: int, total: int) -> None:
        if phase not in bars:
            for bar in bars.values():
                bar.close()
            bars[phase] = tqdm(total=total, desc=phase, unit="view" if phase == "render"
                               else "step", disable=args.quiet, leave=False)
        bars[phase].update(done - bars[phase].n)

    try:
        result = segment_scene(scene, views, settings, mask_embeddings=embeddings,
                               progress=progress)
    finally:
        for bar in bars.values():
            bar.close()
    if suffix == ".csgs":
        from csgs_codec.codec.describe import describe_bitstream
        from csgs_codec.codec.encoder import Encoder

        data = Encoder(quality=args.quality).encode(result.scene)
        share = describe_bitstream(data)["semantic_share_percent"]
        written = f"{len(data):,} bytes, semantic layer {share:.1f}% of the file"
    else:
        data = ply_bytes(result.scene)
        written = f"{len(data):,} bytes, features as {', '.join(result.scene.semantic_names)}"
    write_atomically(output, data)
    instances = result.instances
    print(f"{output}: {instances.count} instances over {len(scene):,} Gaussians "
          f"(largest {instances.counts[0]:,}); {written}")
    times = ", ".join(f"{k} {v:.1f} s" for k, v in result.seconds.items())
    print(f"time: {times}")
    return 0


def read_mask_embeddings(folder: Path, views) -> list:
    """Per view, the (I, E) array in ``folder/<image stem>.npy`` (no pickles).

    Raises:
        InputError: a missing folder or file, or a file that is not a 2-D numeric .npy.
    """
    import numpy as np

    from csgs_codec.untrusted import read_npy

    if not folder.is_dir():
        raise InputError("mask embeddings folder not found", file=folder)
    arrays = []
    for view in views:
        path = folder / f"{Path(view.name).stem}.npy"
        if not path.is_file():
            raise InputError(f"no mask embeddings for view '{view.name}'", file=path)
        array = read_npy(path, 1 << 30, what="mask embeddings", kinds="iuf")
        if array.ndim != 2:
            raise InputError(f"expected a 2-D numeric array (mask id x value), got "
                             f"{array.shape} {array.dtype}", file=path)
        arrays.append(array.astype(np.float32))
    return arrays
