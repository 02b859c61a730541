/**
 * The base layer of a standard scene: the scene header SCNE (§12.5) and the positions of
 * GEOM (§12.6, §15), OUTQ (§12.20, in far_points.mjs) and OUTL (§12.7).
 */

import { ByteReader } from './bytes.mjs';
import { checkFinite, single } from './chunks.mjs';
import { FormatError } from './errors.mjs';
import { readFarPoints } from './far_points.mjs';
import { decodeGeometry } from './geometry.mjs';

/** The SCNE payload (§12.5). */
export function readHeader(container) {
  const [data, offset] = single(container, 'SCNE');
  const r = new ByteReader(data, offset, 'SCNE');
  const count = r.varint('gaussian_count', 2 ** 28);
  const stored = r.u8('sh_degree_stored');
  const coded = r.u8('sh_degree_coded');
  const quality = r.u8('quality');
  const origin = [r.f64('grid_origin_x'), r.f64('grid_origin_y'), r.f64('grid_origin_z')];
  const cell = r.f64('grid_cell');
  const bits = r.u8('grid_bits');
  const far = r.varint('far_count', count);
  r.expectEnd('the scene header');
  if (stored > 3 || coded > stored) throw r.error(`SH degrees stored ${stored} / coded ${coded} are invalid`);
  if (!origin.every(Number.isFinite) || !(Number.isFinite(cell) && cell > 0)) throw r.error('grid origin and cell must be finite, cell > 0');
  if (bits > 21) throw r.error(`grid_bits ${bits} exceeds 21`);
  return { count, stored, coded, quality, origin, cell, bits, far };
}

/** Base layer: float32 positions written into ``positions`` (§12.4 "Positions", §12.6,
 * §12.7, §12.20): grid points, then OUTQ's, then OUTL's; returns the grid cells. */
export function decodePositions(container, header, positions) {
  const gridCount = header.count - header.far;
  const [data, offset] = single(container, 'GEOM');
  let cells;
  try {
    cells = decodeGeometry(data, gridCount);
  } catch (err) {
    if (err instanceof FormatError) throw new FormatError(err.detail, { chunk: 'GEOM', offset: offset + (err.offset ?? 0) });
    throw err;
  }
  if (cells.count !== gridCount) throw new FormatError(`geometry holds ${cells.count} points, the header says ${gridCount}`, { chunk: 'GEOM', offset });
  const limit = 2 ** Math.max(header.bits, 1);
  if (header.bits < 21) {
    for (const axis of [cells.x, cells.y, cells.z]) {
      for (let i = 0; i < axis.length; i++) if (axis[i] >= limit) throw new FormatError('a point lies outside the header\'s grid', { chunk: 'GEOM', offset });
    }
  }
  const [ox, oy, oz] = header.origin;
  const cell = header.cell;
  for (let i = 0; i < gridCount; i++) {
    positions[3 * i] = ox + cells.x[i] * cell;
    positions[3 * i + 1] = oy + cells.y[i] * cell;
    positions[3 * i + 2] = oz + cells.z[i] * cell;
  }
  if (header.far) {
    positions.set(farPositions(container, header), 3 * gridCount);
  } else {
    for (const code of ['OUTQ', 'OUTL']) refuseChunk(container, code, 'the header declares no far points');
  }
  checkFinite(positions, 'GEOM');
  return cells;
}

/** The far_count far positions (§12.4 "Order of the Gaussians"): those of OUTQ (§12.20),
 * when present, then those of OUTL (§12.7). */
function farPositions(container, header) {
  const far = new Float32Array(3 * header.far);
  let q = 0;
  if (container.toc.entries.some((e) => e.type === 'OUTQ')) {
    const [data, offset] = single(container, 'OUTQ');
    const points = readFarPoints(data, offset, header.far);
    far.set(points);
    q = points.length / 3;
  }
  const exact = header.far - q;
  if (!exact) {
    refuseChunk(container, 'OUTL', 'OUTQ holds every far point');
    return far;
  }
  const [outl, at] = single(container, 'OUTL');
  const r = new ByteReader(outl, at, 'OUTL');
  const n = r.varint('far_count', exact);
  if (n !== exact) throw r.error(`${n} outliers, the header and OUTQ leave ${exact}`);
  if (3 * n > Math.floor(r.remaining / 4)) {
    throw r.error(`truncated: field 'positions' needs ${3 * n} x 4 bytes`, r.baseOffset + r.bytes.length);
  }
  for (let i = 3 * q; i < 3 * header.far; i++) far[i] = r.f32('positions');
  r.expectEnd('the outlier list');
  checkFinite(far.subarray(3 * q), 'OUTL');
  return far;
}

/** FormatError at the frame of a ``code`` chunk that ``container`` must not hold. */
function refuseChunk(container, code, why) {
  const entry = container.toc.entries.find((e) => e.type === code);
  if (entry) throw new FormatError(`unexpected ${code} chunk: ${why}`, { chunk: code, offset: entry.offset });
}
