"""``csgs synthetic DIR``: write a seeded synthetic training dataset (images, instance masks,
cameras as transforms.json, and the ground-truth scene.ply) to try ``csgs train`` on."""

from __future__ import annotations

import re
from pathlib import Path

from csgs_codec.errors import InputError

NAME = "synthetic"
#: Views x width x height a dataset may hold (its images stay in memory while rendering).
MAX_TOTAL_PIXELS = 200_000_000
HELP = ("write a seeded synthetic dataset of labelled objects (images, masks, "
        "transforms.json, scene.ply) for 'csgs train'")


def add_arguments(parser) -> None:
    """Arguments of ``csgs synthetic``."""
    parser.add_argument("folder", help="output folder (created; existing files are replaced)")
    parser.add_argument("--objects", type=int, default=3, metavar="K",
                        help="labelled objects (default 3)")
    parser.add_argument("--gaussians", type=int, default=300, metavar="N",
                        help="Gaussians per object (default 300)")
    parser.add_argument("--views", type=int, default=12, metavar="V",
                        help="orbit views (default 12)")
    parser.add_argument("--size", default="96x72", metavar="WxH",
                        help="image size (default 96x72)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def run(args) -> int:
    """Render the dataset and write it; print where it went."""
    from csgs_codec.train.synthetic import make_synthetic_dataset

    match = re.fullmatch(r"(\d+)x(\d+)", args.size)
    if not match:
        raise InputError(f"--size must look like 96x72, got {args.size!r}", property="size")
    width, height = int(match.group(1)), int(match.group(2))
    limits = {"objects": (1, 64), "gaussians": (1, 100_000), "views": (1, 1000)}
    for name, (low, high) in limits.items():
        if not low <= getattr(args, name) <= high:
            raise InputError(f"--{name} must be {low}..{high}", property=name)
    if not (8 <= width <= 4096 and 8 <= height <= 4096):
        raise InputError("--size must be 8..4096 pixels per side", property="size")
    if args.views * width * height > MAX_TOTAL_PIXELS:
        raise InputError(f"{args.views} views of {width}x{height} exceed "
                         f"{MAX_TOTAL_PIXELS:,} pixels in all", property="views")
    folder = Path(args.folder)
    writable_folder(folder)  # before rendering, not after
    dataset = make_synthetic_dataset(args.seed, objects=args.objects,
                                     gaussians_per_object=args.gaussians, views=args.views,
                                     width=width, height=height)
    target = dataset.write(args.folder)
    print(f"{target}: {args.views} views {width}x{height}, {args.objects} objects, "
          f"{len(dataset.scene):,} Gaussians (ground truth in scene.ply)")
    return 0


def writable_folder(folder: Path) -> None:
    """Create ``folder`` (and its parents) unless it exists, and check files can be made in
    it and in its masks/ and images/ (when they exist).

    Raises:
        InputError: naming the folder: not a folder, cannot be created, or not writable.
    """
    import os

    try:
        if folder.exists() and not folder.is_dir():
            raise InputError("exists and is not a folder", file=folder)
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder: {exc.strerror or exc}",
                         file=folder) from None
    for place in (folder, folder / "masks", folder / "images"):
        if place.is_dir() and not os.access(place, os.W_OK | os.X_OK):
            raise InputError("folder is not writable", file=place)
