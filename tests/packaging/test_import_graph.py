"""csgs_codec's modules import each other without cycles, counting imports inside functions.

A cycle hidden behind a function-level import still ties two modules into one unit that
cannot be read, tested or moved apart; the layering (format below entropy below codec, ...)
depends on there being none.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "csgs_codec"


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """Module name -> the csgs_codec modules it imports anywhere in its body."""
    modules = _modules()

    def owner(name: str) -> str:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name

    graph = {}
    for name, path in modules.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                deps |= {owner(a.name) for a in node.names if a.name.startswith("csgs_codec")}
            elif (isinstance(node, ast.ImportFrom) and node.level == 0 and node.module
                  and node.module.startswith("csgs_codec")):
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    deps.add(full if full in modules else owner(node.module))
        graph[name] = deps - {name, "csgs_codec"}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (iterative Tarjan)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_module_of_csgs_codec_is_in_an_import_cycle():
    graph = import_graph()
    assert len(graph) > 100
    assert cycles(graph) == []


def _reachable(graph: dict[str, set[str]], root: str) -> set[str]:
    """Every module ``root`` imports, directly or through others."""
    seen, stack = set(), [root]
    while stack:
        for dep in graph.get(stack.pop(), ()):
            if dep not in seen:
                seen.add(dep)
                stack.append(dep)
    return seen


def test_the_decoders_import_no_encoder_decision():
    """csgs_codec.decisions holds what only the encoder decides (presets, allocation, rate
    control, ...); a decoder that needed one of them would read something the format does
    not record."""
    graph = import_graph()
    assert "csgs_codec.decisions.presets" in graph
    for decoder in ("csgs_codec.codec.decoder", "csgs_codec.codec.anchor_decoder",
                    "csgs_codec.chunks.color_streams"):
        assert decoder in graph
        assert not {m for m in _reachable(graph, decoder) if m.startswith("csgs_codec.decisions")}


#: The packages of csgs_codec from the bottom up: a package imports only packages of lower
#: rank (modules of the same package import each other freely). A new package must be placed
#: here; equal ranks do not import each other.
PACKAGE_RANKS = {
    "errors": 0,
    "untrusted": 1, "atomic_write": 1, "progress": 1, "extras": 1,
    "format": 2,                                  # the .csgs container
    "entropy": 3, "scene": 3,                     # coders; scene classes
    "attributes": 4,                              # values <-> integers (FORMAT §12)
    "chunks": 5, "interchange": 5, "render": 5, "model": 5,
    "metrics": 6, "semantic": 6, "bake": 6,       # bake: anchors -> standard Gaussians
    "levels": 6,                                  # coarser levels of detail by merging
    "decisions": 7,                               # what only the encoder decides
    "codec": 8,                                   # Encoder, Decoder, anchors, tiles, files
    "train": 9, "web": 9, "js": 9,
    "": 10,                                       # csgs_codec/__init__.py
}


def _package(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """Imports from a package to one of equal or higher rank in :data:`PACKAGE_RANKS`."""
    bad = []
    for module, deps in graph.items():
        here = _package(module)
        for dep in deps:
            there = _package(dep)
            if there != here and PACKAGE_RANKS[there] >= PACKAGE_RANKS[here]:
                bad.append(f"{module} -> {dep}")
    return sorted(bad)


def test_every_package_has_a_rank():
    packages = {_package(m) for m in import_graph()}
    assert packages <= set(PACKAGE_RANKS), packages - set(PACKAGE_RANKS)


def test_packages_import_only_lower_layers():
    """The layering a reader relies on: the container below the coders, attribute coding
    below the chunks that carry it, encoder decisions below the Encoder and Decoder."""
    assert layer_violations(import_graph()) == []


def test_the_layer_check_sees_an_upward_import():
    graph = {"csgs_codec.attributes.float_stream": {"csgs_codec.chunks.color_streams"},
             "csgs_codec.chunks.color_streams": set()}
    assert layer_violations(graph) == [
        "csgs_codec.attributes.float_stream -> csgs_codec.chunks.color_streams"]
