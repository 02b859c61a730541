"""``csgs combine-masks SOURCE -o MASKS``: per-object binary masks (SAM's, one folder per
view) to the one instance-id image per view that ``csgs segment --masks`` reads."""

from __future__ import annotations

from pathlib import Path

from csgs_codec.errors import InputError

NAME = "combine-masks"
HELP = ("turn per-object binary masks (one folder per view, one image per object, as SAM "
        "writes them) into one instance-id PNG per view for 'csgs segment --masks' "
        "(docs/masks.md)")


def add_arguments(parser) -> None:
    """Arguments of ``csgs combine-masks``."""
    parser.add_argument("source", help="folder holding SOURCE/<view stem>/<object>.png, any "
                                       "non-zero pixel inside the object")
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="folder for <view stem>.png (created if missing): ids 1, 2, ... "
                             "in natural file-name order, 0 where no object is; where "
                             "objects overlap the smaller wins (equal size: the later)")


def run(args) -> int:
    """Combine every view's object masks and write one id PNG per view, atomically."""
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_codec.atomic_write import write_atomically
    from csgs_codec.train.combine_masks import combine_object_masks, find_object_masks, id_png

    output = Path(args.output)
    if output.exists() and not output.is_dir():
        raise InputError("output exists and is not a folder", file=output)
    views = find_object_masks(args.source)
    targets = [output / f"{view.name}.png" for view in views]
    refuse_overwriting_inputs([("-o", target) for target in targets],
                              [("the object masks", file) for view in views
                               for file in view.files])
    try:
        output.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output folder: {exc.strerror or exc}",
                         file=output) from None
    most = 0
    for view, target in zip(views, targets):
        write_atomically(target, id_png(combine_object_masks(view.files)))
        most = max(most, len(view.files))
    print(f"{output}: {len(views)} id mask(s), up to {most} objects a view; give them to "
          f"'csgs segment ... --masks {output} --ignore-id 0' (0: no object)")
    return 0
