"""``csgs info FILE``: what is in a scene file (any format csgs reads) or a .csgs bitstream."""

from __future__ import annotations

import json
import os

NAME = "info"
HELP = ("show what a scene file (PLY, compressed PLY, .splat, .ksplat, SPZ, SOG, GLB) or a "
        ".csgs bitstream holds")


def add_arguments(parser) -> None:
    """Arguments of ``csgs info``."""
    parser.add_argument("file", help="a scene file or SOG folder (format recognised by content) "
                                     "or a .csgs bitstream")
    parser.add_argument("--json", action="store_true", help="print machine-readable JSON")
    parser.add_argument("--sanitize", action="store_true",
                        help="drop Gaussians with NaN/Inf values instead of failing")


def run(args) -> int:
    """Print the summary of ``args.file`` as text or JSON."""
    from csgs_cli.scene_input import is_anchor_input
    from csgs_codec.interchange import detect_format

    if is_anchor_input(args.file):
        facts = describe_anchor_input(args.file)
        print(json.dumps(facts, indent=2) if args.json else format_anchor_facts(facts))
        return 0
    if detect_format(args.file) == "csgs":
        from csgs_codec.codec.describe import describe_bitstream
        from csgs_codec.format import format_description

        facts = describe_bitstream(args.file, verify=True)
        print(json.dumps(facts, indent=2) if args.json
              else with_semantic_share(format_description(facts), facts))
        return 0
    facts = describe_file(args.file, sanitize=args.sanitize)
    print(json.dumps(facts, indent=2) if args.json else format_scene_facts(facts))
    return 0


def describe_anchor_input(path: str) -> dict:
    """JSON-ready facts about a Scaffold-GS anchor PLY or checkpoint folder: anchors, feature
    width, offsets, kept slots, MLPs, semantic channels, labels and the bounding box."""
    from csgs_cli.scene_input import load_anchor_scene

    scene = load_anchor_scene(path)
    lo = scene.positions.min(axis=0) if len(scene) else [0.0] * 3
    hi = scene.positions.max(axis=0) if len(scene) else [0.0] * 3
    return {"file": path, "kind": "anchors", "format": "scaffold-gs",
            "format_name": "Scaffold-GS anchor scene", "bytes": _size(path),
            "anchors": len(scene), "feature_width": scene.feat_dim,
            "offsets_per_anchor": scene.n_offsets, "kept_slots": scene.active_offsets(),
            "mlps": scene.mlps is not None,
            "semantic_channels": list(scene.semantic_names) if scene.semantic is not None
            else [],
            "labels": None if scene.labels is None else int(len(set(scene.labels.tolist()))),
            "bounding_box": {"min": [float(v) for v in lo], "max": [float(v) for v in hi]}}


def format_anchor_facts(f: dict) -> str:
    """Human-readable text for :func:`describe_anchor_input`'s facts."""
    vec = lambda v: "(" + ", ".join(f"{x:.4g}" for x in v) + ")"  # noqa: E731
    lines = [f"{f['file']}: {f['format_name']}, {f['bytes']:,} bytes",
             f"  anchors          {f['anchors']:,} (feature width {f['feature_width']}, "
             f"{f['offsets_per_anchor']} offsets each, {f['kept_slots']:,} kept slots)",
             f"  MLPs             {'yes' if f['mlps'] else 'none beside the PLY'}",
             f"  bounding box     {vec(f['bounding_box']['min'])} .. "
             f"{vec(f['bounding_box']['max'])}"]
    if f["semantic_channels"]:
        lines.append(f"  semantic         {len(f['semantic_channels'])} channels: "
                     + ", ".join(f["semantic_channels"]))
    if f["labels"] is not None:
        lines.append(f"  labels           {f['labels']} distinct")
    return "\n".join(lines)


def with_semantic_share(text: str, facts: dict) -> str:
    """``text`` with a line giving the semantic layer's share of the file, placed after the
    semantic layer's line (or last when there is none)."""
    share = (f"  semantic share   {facts['semantic_share_percent']:.2f}% of the file "
             "(semantic layer bytes / file bytes)")
    lines = text.split("\n")
    at = next((i + 1 for i, line in enumerate(lines) if line.startswith("  semantic ")),
              len(lines))
    return "\n".join(lines[:at] + [share] + lines[at:])


def describe_file(path: str, *, sanitize: bool = False) -> dict:
    """JSON-ready facts about the scene in ``path`` (any format csgs reads): ``format``
    (short name), ``format_name`` (with its version), ``format_version``, ``lossy``,
    ``details`` (format-specific), the scene summary, and for PLY input ``ply_format``."""
    from csgs_codec.codec.files import read_scene_with_report
    from csgs_codec.scene.summary import summarize_scene

    scene, source = read_scene_with_report(path, sanitize=sanitize, layers="color,semantic")
    details = dict(source.details)
    facts = {"file": path, "kind": source.format, "format": source.format,
             "format_name": source.title(), "format_version": source.version,
             "lossy": source.lossy, "bytes": _size(path)}
    if source.format == "ply":
        facts["ply_format"] = details.pop("ply_format")
    facts["details"] = {k: v for k, v in details.items()
                        if k not in ("ignored_properties", "nonfinite_dropped")}
    facts.update(summarize_scene(scene))
    facts["ignored_properties"] = details.get("ignored_properties", [])
    facts["nonfinite_dropped"] = details.get("nonfinite_dropped", 0)
    return facts


def _size(path: str) -> int:
    """Bytes of a file, or of the files in a folder (a SOG folder)."""
    if os.path.isdir(path):
        return sum(os.path.getsize(os.path.join(path, f)) for f in os.listdir(path)
                   if os.path.isfile(os.path.join(path, f)))
    return os.path.getsize(path)


def _range(entry: dict) -> str:
    if "min" not in entry:
        return "-"
    return f"{min(entry['min']):.6g} .. {max(entry['max']):.6g}"


def format_scene_facts(f: dict) -> str:
    """Human-readable text for the facts of a scene file (see :func:`describe_file`)."""
    lo, hi = f["bounding_box"]["min"], f["bounding_box"]["max"]
    vec = lambda v: "(" + ", ".join(f"{x:.4g}" for x in v) + ")"  # noqa: E731
    lines = [
        f"{f['file']}: {f['format_name']}"
        + (f" ({f['ply_format']})" if "ply_format" in f else "") + f", {f['bytes']:,} bytes"
        + (", lossy (quantized by its format)" if f["lossy"] else ""),
        f"  Gaussians        {f['gaussians']:,}",
        f"  SH degree        {f['sh_degree_stored']} stored, {f['sh_degree_in_use']} in use"
        + (f" (all-zero bands: {f['zero_sh_bands']})" if f["zero_sh_bands"] else ""),
        f"  bounding box     {vec(lo)} .. {vec(hi)}",
        f"  robust extent    {f['robust']['extent']:.4g} around {vec(f['robust']['centre'])}"
        f" ({f['robust']['percentile']:g}-{100 - f['robust']['percentile']:g} percentile box)",
        "  attributes (raw stored values):",
    ]
    for name, entry in f["attributes"].items():
        lines.append(f"    {name:<12} {entry['channels']:>3} ch   {_range(entry)}")
    if f["constant_channels"]:
        const = "; ".join(f"{k} {v}" for k, v in f["constant_channels"].items())
        lines.append(f"  constant channels {const}")
    if f["semantic_channels"]:
        lines.append(f"  semantic         {len(f['semantic_channels'])} channels: "
                     + ", ".join(f["semantic_channels"]))
    if f["labels"] is not None:
        lines.append(f"  labels           {f['labels']} distinct")
    if f["ignored_properties"]:
        lines.append(f"  ignored          {', '.join(f['ignored_properties'])}")
    if f["nonfinite_dropped"]:
        lines.append(f"  dropped          {f['nonfinite_dropped']} Gaussians with NaN/Inf")
    if f["details"]:
        lines.append("  format details   " + ", ".join(f"{k} {v}" for k, v in f["details"].items()))
    return "\n".join(lines)
