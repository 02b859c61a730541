"""How an encode walks the package: the cross-module calls ``Encoder.encode`` makes (issue 33).

    .venv/bin/python benchmarks/encode_walk.py [--scene samples/donut.ply] [--count 5000]
        [--target-psnr DB] [--out FILE]

Encodes the first ``--count`` Gaussians of the scene with the default encoder (quality 5,
step allocation and the color hyperprior as their defaults decide; or searching for
``--target-psnr``) under ``sys.setprofile``
and records every Python call from one module of ``csgs_codec`` into another. Each distinct
edge (caller module, callee module, callee function) counts once, in the order it first
happens, so loops do not inflate the counts:

- ``stays``: distinct cross-module calls; ``files``: modules entered;
- ``climbs``: calls into a module that imports the caller's module (directly or not): a call
  back up the layering (callbacks, a lower layer driving a higher one);
- ``returns``: calls into a module the walk had already entered through another edge.

Run it on two checkouts (``PYTHONPATH=/path/to/checkout``) to compare layouts: the counts
depend on the code's structure, not on the machine.
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402


def _package_root() -> Path:
    import csgs_codec

    return Path(csgs_codec.__file__).resolve().parent


def _module_of(path: str, root: Path) -> str | None:
    """``csgs_codec.a.b`` of a file under ``root``, or None outside it."""
    try:
        rel = Path(path).resolve().relative_to(root)
    except ValueError:
        return None
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(["csgs_codec", *parts])


def import_graph(root: Path) -> dict[str, set[str]]:
    """module -> the csgs_codec modules it imports (any import statement in its source)."""
    graph: dict[str, set[str]] = {}
    for path in root.rglob("*.py"):
        name = _module_of(str(path), root)
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(
                    "csgs_codec"):
                found.add(node.module)
                found.update(f"{node.module}.{a.name}" for a in node.names)
            elif isinstance(node, ast.Import):
                found.update(a.name for a in node.names if a.name.startswith("csgs_codec"))
        graph[name] = found
    return graph


def _importers(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """module -> every module that imports it, directly or through others."""
    direct: dict[str, set[str]] = {m: set() for m in graph}
    for module, imported in graph.items():
        for target in imported:
            if target in direct:
                direct[target].add(module)
    closure = {}
    for module in direct:
        seen, todo = set(), [module]
        while todo:
            for up in direct.get(todo.pop(), ()):
                if up not in seen:
                    seen.add(up)
                    todo.append(up)
        closure[module] = seen
    return closure


def walk(scene, root: Path, target_psnr: float | None = None) -> list[tuple[str, str, str]]:
    """The distinct (caller module, callee module, callee function) edges of one encode (at
    quality 5, or searching for ``target_psnr``), in the order they first happen."""
    from csgs_codec import Encoder

    edges: dict[tuple[str, str, str], None] = {}
    modules: dict[str, str | None] = {}

    def module(code) -> str | None:
        name = modules.get(code.co_filename, "")
        if name == "":
            name = modules[code.co_filename] = _module_of(code.co_filename, root)
        return name

    def profile(frame, event, _arg):
        if event != "call":
            return
        callee = module(frame.f_code)
        if callee is None:
            return
        caller = frame.f_back
        while caller is not None and module(caller.f_code) is None:
            caller = caller.f_back  # through numpy, threads' trampolines and the like
        if caller is None:
            return
        source = module(caller.f_code)
        if source != callee:
            edges.setdefault((source, callee, frame.f_code.co_name), None)

    encoder = Encoder(quality=5) if target_psnr is None else Encoder(target_psnr=target_psnr)
    sys.setprofile(profile)
    try:
        encoder.encode(scene)
    finally:
        sys.setprofile(None)
    return list(edges)


def counts(edges: list[tuple[str, str, str]], graph: dict[str, set[str]]) -> dict:
    """The walk's figures (module docstring) from its ordered distinct ``edges``."""
    importers = _importers(graph)
    entered: dict[str, tuple[str, str, str]] = {}
    climbs = returns = 0
    for edge in edges:
        source, target, _ = edge
        if target in importers.get(source, set()):  # the callee imports the caller
            climbs += 1
        if target in entered and entered[target] != edge:
            returns += 1
        entered.setdefault(target, edge)
    files = {e[0] for e in edges} | {e[1] for e in edges}
    return {"stays": len(edges), "files": len(files), "climbs": climbs, "returns": returns}


def main() -> int:
    """Encode under the profiler and write the walk's counts."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(Path(__file__).resolve().parents[1] / "samples"
                                               / "donut.ply"))
    parser.add_argument("--count", type=int, default=5000)
    parser.add_argument("--target-psnr", type=float, default=None,
                        help="walk a rate-controlled encode instead of quality 5")
    parser.add_argument("--out")
    args = parser.parse_args()
    import numpy as np

    from csgs_codec import read_ply

    root = _package_root()
    scene = read_ply(args.scene)
    scene = scene.subset(np.arange(min(args.count, len(scene))))
    edges = walk(scene, root, args.target_psnr)
    graph = import_graph(root)
    row = {"package": str(root), **counts(edges, graph),
           "edges": [" -> ".join((a, f"{b}.{f}")) for a, b, f in edges]}
    emit(document("encode_walk", [row], settings=vars(args)), args.out)
    print({k: v for k, v in row.items() if k != "edges"}, file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
