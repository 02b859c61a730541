"""``csgs info FILE``: what is in a PLY scene or a .csgs bitstream."""

from __future__ import annotations

import json
import os

from csgs_codec.errors import InputError

NAME = "info"
HELP = "show what a scene (.ply) or bitstream (.csgs) holds"
CSGS_MAGIC_PREFIX = b"\x89CSG\r\n\x1a\n"


def add_arguments(parser) -> None:
    """Arguments of ``csgs info``."""
    parser.add_argument("file", help="a 3DGS .ply scene or a .csgs bitstream")
    parser.add_argument("--json", action="store_true", help="print machine-readable JSON")
    parser.add_argument("--sanitize", action="store_true",
                        help="drop Gaussians with NaN/Inf values instead of failing")


def run(args) -> int:
    """Print the summary of ``args.file`` as text or JSON."""
    if is_csgs(args.file):
        from csgs_codec.codec.describe import describe_bitstream
        from csgs_codec.format import format_description

        facts = describe_bitstream(args.file, verify=True)
        print(json.dumps(facts, indent=2) if args.json
              else with_semantic_share(format_description(facts), facts))
        return 0
    _check_ply_signature(args.file)
    facts = describe_file(args.file, sanitize=args.sanitize)
    print(json.dumps(facts, indent=2) if args.json else format_ply_facts(facts))
    return 0


def with_semantic_share(text: str, facts: dict) -> str:
    """``text`` with a line giving the semantic layer's share of the file, placed after the
    semantic layer's line (or last when there is none)."""
    share = (f"  semantic share   {facts['semantic_share_percent']:.2f}% of the file "
             "(semantic layer bytes / file bytes)")
    lines = text.split("\n")
    at = next((i + 1 for i, line in enumerate(lines) if line.startswith("  semantic ")),
              len(lines))
    return "\n".join(lines[:at] + [share] + lines[at:])


def is_csgs(path: str) -> bool:
    """True when ``path`` starts with the .csgs magic (the extension is not trusted)."""
    try:
        with open(path, "rb") as fh:
            return fh.read(len(CSGS_MAGIC_PREFIX)) == CSGS_MAGIC_PREFIX
    except OSError:
        return False  # the PLY path reports the missing or unreadable file


def _check_ply_signature(path: str) -> None:
    """InputError when ``path`` is readable, not empty and starts neither with the .csgs
    magic nor with "ply": say it is neither, rather than only "not a PLY file"."""
    try:
        with open(path, "rb") as fh:
            start = fh.read(len(CSGS_MAGIC_PREFIX))
    except OSError:
        return  # the PLY path reports the missing or unreadable file
    if start and not start.startswith(b"ply"):
        raise InputError("neither a .csgs bitstream (no .csgs magic) nor a PLY "
                         "file (does not start with 'ply')", file=path, offset=0)


def describe_file(path: str, *, sanitize: bool = False) -> dict:
    """JSON-ready facts about ``path`` (a PLY scene)."""
    from csgs_codec.scene.ply_io import read_ply_with_report
    from csgs_codec.scene.summary import summarize_scene

    if os.path.isdir(path):
        raise InputError("is a directory", file=path)
    scene, report = read_ply_with_report(path, sanitize=sanitize)
    facts = {"file": path, "kind": "ply", "bytes": os.path.getsize(path),
             "ply_format": report.format}
    facts.update(summarize_scene(scene))
    facts["ignored_properties"] = report.dropped_properties
    facts["nonfinite_dropped"] = report.nonfinite_dropped
    return facts


def _range(entry: dict) -> str:
    if "min" not in entry:
        return "-"
    return f"{min(entry['min']):.6g} .. {max(entry['max']):.6g}"


def format_ply_facts(f: dict) -> str:
    """Human-readable text for the facts of a PLY scene."""
    lo, hi = f["bounding_box"]["min"], f["bounding_box"]["max"]
    vec = lambda v: "(" + ", ".join(f"{x:.4g}" for x in v) + ")"  # noqa: E731
    lines = [
        f"{f['file']}: 3DGS PLY ({f['ply_format']}), {f['bytes']:,} bytes",
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
    return "\n".join(lines)
