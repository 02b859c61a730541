"""``csgs query scene.csgs --embedding QUERY.npy [-o object.ply]``: the instance whose
embedding best matches a query embedding (open-vocabulary selection), written as a PLY."""

from __future__ import annotations

from pathlib import Path

NAME = "query"
HELP = ("select the instance whose embedding best matches a query embedding (.npy) in a "
        "segmented .csgs and write its Gaussians as a .ply")
#: Instances listed with their scores.
SHOWN = 5


def add_arguments(parser) -> None:
    """Arguments of ``csgs query``."""
    parser.add_argument("scene", help="a .csgs written by 'csgs segment' with --mask-embeddings")
    parser.add_argument("--embedding", required=True, metavar="NPY",
                        help="the query: a .npy holding one vector in the space of the "
                             "scene's instance embeddings (e.g. a CLIP text embedding)")
    parser.add_argument("-o", "--output", metavar="PLY",
                        help="write the selected Gaussians here (default: only print)")


def run(args) -> int:
    """Rank the instances, print the best ones, write the best one's Gaussians."""
    import numpy as np

    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_cli.scene_input import load_scene
    from csgs_codec.atomic_write import check_output
    from csgs_codec.interchange.ply_io import write_ply
    from csgs_codec.semantic.query import query_instances
    from csgs_codec.untrusted import read_npy

    refuse_overwriting_inputs([("-o", args.output)],
                              [("the scene", args.scene), ("--embedding", args.embedding)])
    if args.output:
        check_output(Path(args.output), [args.scene])
    query = _read_vector(Path(args.embedding), read_npy)
    scene = load_scene(args.scene, command=NAME, layers="color,semantic")
    result = query_instances(scene, query)
    sizes = np.bincount(result.rows[result.rows >= 0], minlength=len(result.scores))
    for rank, row in enumerate(result.ranking[:SHOWN]):
        members = int(sizes[row])
        print(f"{rank + 1}. instance {row}: cosine {result.scores[row]:.4f}, "
              f"{members:,} Gaussians")
    if args.output:
        write_ply(scene.subset(result.mask), Path(args.output), [args.scene])
        print(f"wrote instance {result.instance} ({result.count:,} Gaussians) to "
              f"{args.output}")
    return 0


def _read_vector(path: Path, read_npy):
    """The query vector in a .npy file, float64 (no pickles, header checked first)."""
    import numpy as np

    return read_npy(path, 1 << 26, what="a query embedding", kinds="iuf").astype(np.float64)
