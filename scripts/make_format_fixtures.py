"""Make the interchange-format fixtures in tests/data/formats/ with independent tools (run once).

The fixtures are small real scenes converted by the tools that define or popularised each
format, so the readers are tested against files csgs did not write:

* ``@playcanvas/splat-transform`` 3.7.0 (``cd benchmarks && npm ci``): compressed PLY, SOG
  (zip and folder), SPZ v3/v4, glTF/GLB with KHR_gaussian_splatting; it also decodes every
  fixture it can read to a PLY under ``oracle/`` (what an independent reader makes of it).
* Niantic's spz library (WebAssembly build, bundled in splat-transform as ``@adobe/spz``):
  SPZ v2.
* antimatter15's ``convert.py`` (github.com/antimatter15/splat): ``.splat``.
* mkkellogg's GaussianSplats3D 0.4.7 (npm ``@mkkellogg/gaussian-splats-3d`` and ``three``):
  ``.ksplat`` at compression levels 0, 1 and 2 with SH degree 0, 1 and 2.

Usage::

    python scripts/make_format_fixtures.py --ksplat-tool DIR --splat-convert convert.py

``DIR`` is a folder whose ``node_modules`` holds the GaussianSplats3D and three packages.
The SOG v1 fixture (no public tool writes that retired version any more) is made by
``tests/interchange/sog_v1_maker.py`` and decoded by splat-transform like the others.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "tests" / "data" / "formats"
SPLAT_TRANSFORM = REPO / "benchmarks" / "node_modules" / "@playcanvas" / "splat-transform"
LEICA = REPO.parent / "shared" / "data" / "real_sh3" / "leica_sofort_top8192.ply"
DONUT = REPO / "samples" / "donut.ply"


def slice_ply(source: Path, target: Path, step: int, count: int) -> None:
    """Copy every ``step``-th vertex row (``count`` rows) of a binary little-endian PLY,
    keeping its header (property order, comments) apart from the vertex count."""
    data = source.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").split("\n")
    names = [line.split()[2] for line in header if line.startswith("property float")]
    row = 4 * len(names)
    total = (len(data) - end) // row
    rows = np.frombuffer(data, np.uint8, offset=end).reshape(total, row)[::step][:count]
    header = [f"element vertex {len(rows)}" if line.startswith("element vertex") else line
              for line in header]
    header = [line for line in header if not line.startswith("comment subset")]
    target.write_bytes("\n".join(header).encode("ascii") + rows.tobytes())


def splat_transform(*args: str) -> None:
    """Run the splat-transform CLI with ``args`` (CPU only, quiet, overwriting)."""
    cli = SPLAT_TRANSFORM / "bin" / "cli.mjs"
    subprocess.run(["node", str(cli), "--quiet", "--overwrite", "--gpu", "cpu", *args],
                   check=True)


SPZ_V2_SCRIPT = """
import createSpzModule from '{module}';
import {{ readFileSync, writeFileSync }} from 'fs';
const [input, output] = process.argv.slice(2);
const text = readFileSync(input);
const end = text.indexOf('end_header\\n') + 'end_header\\n'.length;
const header = text.subarray(0, end).toString('ascii').split('\\n');
const names = header.filter(l => l.startsWith('property float')).map(l => l.split(' ')[2]);
const count = parseInt(header.find(l => l.startsWith('element vertex')).split(' ')[2]);
const body = new Float32Array(text.buffer.slice(text.byteOffset + end,
                              text.byteOffset + end + count * names.length * 4));
const col = name => {{ const k = names.indexOf(name); return i => body[i * names.length + k]; }};
const rest = names.filter(n => n.startsWith('f_rest_')).length;
const per = rest / 3;
const cloud = {{ numPoints: count, shDegree: {{0: 0, 3: 1, 8: 2, 15: 3}}[per],
  antialiased: false, extensions: [],
  positions: new Float32Array(count * 3), scales: new Float32Array(count * 3),
  rotations: new Float32Array(count * 4), alphas: new Float32Array(count),
  colors: new Float32Array(count * 3), sh: new Float32Array(count * rest) }};
for (let i = 0; i < count; i++) {{
  ['x', 'y', 'z'].forEach((n, j) => cloud.positions[i * 3 + j] = col(n)(i));
  ['scale_0', 'scale_1', 'scale_2'].forEach((n, j) => cloud.scales[i * 3 + j] = col(n)(i));
  ['f_dc_0', 'f_dc_1', 'f_dc_2'].forEach((n, j) => cloud.colors[i * 3 + j] = col(n)(i));
  ['rot_1', 'rot_2', 'rot_3', 'rot_0'].forEach((n, j) => cloud.rotations[i * 4 + j] = col(n)(i));
  cloud.alphas[i] = col('opacity')(i);
  for (let k = 0; k < per; k++) for (let c = 0; c < 3; c++)
    cloud.sh[i * rest + k * 3 + c] = col('f_rest_' + (c * per + k))(i);
}}
const spz = await createSpzModule();
const bytes = spz.saveSpzToBuffer(cloud, {{ version: 2, from: spz.CoordinateSystem.UNSPECIFIED,
                                           sh1Bits: 5, shRestBits: 4 }});
writeFileSync(output, bytes);
"""

KSPLAT_SCRIPT = """
import * as GS from '@mkkellogg/gaussian-splats-3d';
import {{ readFileSync, writeFileSync }} from 'fs';
const [input, output, level, degree] = process.argv.slice(2);
const data = readFileSync(input);
const buffer = data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength);
const array = GS.PlyParser.parseToUncompressedSplatArray(buffer, parseInt(degree));
const generator = GS.SplatBufferGenerator.getStandardGenerator(1, parseInt(level), 0);
writeFileSync(output, Buffer.from(generator.generateFromUncompressedSplatArray(array).bufferData));
"""


def main() -> int:
    """Write the fixtures into tests/data/formats/ (existing files are replaced)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ksplat-tool", required=True, type=Path)
    parser.add_argument("--splat-convert", required=True, type=Path)
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "oracle").mkdir(exist_ok=True)
    sh3, sh0 = OUT / "brush_sh3.ply", OUT / "donut_sh0.ply"
    slice_ply(LEICA, sh3, step=41, count=200)
    slice_ply(DONUT, sh0, step=152, count=300)

    splat_transform(str(sh3), str(OUT / "brush_sh3.compressed.ply"))
    splat_transform(str(sh0), str(OUT / "donut_sh0.compressed.ply"))
    splat_transform(str(sh3), str(OUT / "brush_sh3.sog"))
    folder = OUT / "donut_sh0_sog"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    splat_transform(str(sh0), str(folder / "meta.json"))
    splat_transform("--spz-version", "3", str(sh3), str(OUT / "brush_sh3.v3.spz"))
    splat_transform("--spz-version", "4", str(sh3), str(OUT / "brush_sh3.v4.spz"))
    splat_transform("--spz-version", "4", str(sh0), str(OUT / "donut_sh0.v4.spz"))
    splat_transform(str(sh3), str(OUT / "brush_sh3.glb"))

    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "spz_v2.mjs"
        module = SPLAT_TRANSFORM / "dist" / next(
            p.name for p in (SPLAT_TRANSFORM / "dist").glob("spz-*.js")
            if "export { createSpzModule as default }" in p.read_text())
        script.write_text(SPZ_V2_SCRIPT.format(module=module.as_posix()))
        subprocess.run(["node", str(script), str(sh3), str(OUT / "brush_sh3.v2.spz")], check=True)
        ksplat = args.ksplat_tool / "make_ksplat.mjs"
        ksplat.write_text(KSPLAT_SCRIPT.format())
        for name, source, level, degree in [("brush_sh3.l0.ksplat", sh3, 0, 2),
                                            ("brush_sh3.l1.ksplat", sh3, 1, 2),
                                            ("brush_sh3.l2.ksplat", sh3, 2, 2),
                                            ("brush_sh3.l2_sh1.ksplat", sh3, 2, 1),
                                            ("donut_sh0.l1.ksplat", sh0, 1, 0)]:
            subprocess.run(["node", str(ksplat), str(source), str(OUT / name), str(level),
                            str(degree)], check=True, cwd=args.ksplat_tool)
        ksplat.unlink()
    for source in (sh3, sh0):
        subprocess.run([sys.executable, str(args.splat_convert), str(source), "--output",
                        str(OUT / source.with_suffix(".splat").name)], check=True)

    oracles = ["brush_sh3.compressed.ply", "donut_sh0.compressed.ply", "brush_sh3.sog",
               "donut_sh0_sog/meta.json", "brush_sh3.v2.spz", "brush_sh3.v3.spz",
               "brush_sh3.v4.spz", "donut_sh0.v4.spz", "brush_sh3.l0.ksplat",
               "brush_sh3.l1.ksplat", "brush_sh3.l2.ksplat", "brush_sh3.l2_sh1.ksplat",
               "donut_sh0.l1.ksplat", "brush_sh3.splat", "donut_sh0.splat"]
    if (OUT / "brush_sh1_sog_v1" / "meta.json").is_file():
        oracles.append("brush_sh1_sog_v1/meta.json")
    for name in oracles:
        target = OUT / "oracle" / (name.replace("/meta.json", "").replace(".", "_") + ".ply")
        splat_transform(str(OUT / name), str(target))
    return 0


if __name__ == "__main__":
    sys.exit(main())
