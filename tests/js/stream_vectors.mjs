/**
 * Test helper: decodes the bare-stream conformance vectors (spec/vectors/geometry, entropy,
 * histogram) with the JavaScript receiver's modules and prints one JSON line per vector:
 * {"name", "ok", "values"} (integers as decimal strings) or {"name", "ok": false, "offset"}.
 * Usage: node stream_vectors.mjs VECTOR_ROOT [wasm|js]
 */

import { readFileSync, readdirSync } from 'node:fs';
import { join } from 'node:path';

import { FormatError } from '../../csgs_codec/js/errors.mjs';
import { decodeGeometry } from '../../csgs_codec/js/geometry.mjs';
import { decodeHistogram } from '../../csgs_codec/js/histogram.mjs';
import { forwardIntNet, parseIntNet } from '../../csgs_codec/js/intnet.mjs';
import { setRangeCoder } from '../../csgs_codec/js/range_decoder.mjs';
import { decodeSymbols } from '../../csgs_codec/js/residual.mjs';
import { stepSize } from '../../csgs_codec/js/float_stream.mjs';
import { loadTables } from '../../csgs_codec/js/tables_node.mjs';

setRangeCoder(process.argv[3] || 'wasm');
const { family, sine } = loadTables();
const exact = (decoded, i) => (decoded.big && decoded.big.has(i) ? decoded.big.get(i) : BigInt(decoded.values[i]));

function decode(kind, record, bytes) {
  if (kind === 'geometry') {
    const p = decodeGeometry(bytes, 1 << 26);
    return Array.from({ length: p.count }, (_, i) => [p.x[i], p.y[i], p.z[i]].join(' '));
  }
  if (kind === 'residual') {
    const { mean, scale_idx: scales, step_idx: steps } = record.inputs;
    const decoded = decodeSymbols(bytes, Uint8Array.from(scales), scales.length, family, null, 0);
    return scales.map((_, i) => String(BigInt(mean[i]) + BigInt(stepSize(steps[i])) * exact(decoded, i)));
  }
  if (kind === 'histogram') {
    const decoded = decodeHistogram(bytes, record.count, null, 0);
    return Array.from({ length: record.count }, (_, i) => String(exact(decoded, i)));
  }
  const net = parseIntNet(bytes, family, null, 0);
  const positions = record.positions || [];
  const cols = [0, 1, 2].map((d) => Float64Array.from(positions, (p) => p[d]));
  const out = forwardIntNet(net, cols[0], cols[1], cols[2], positions.length, sine);
  const width = out.length / Math.max(positions.length, 1);
  return positions.map((_, i) => Array.from(out.subarray(i * width, (i + 1) * width)).join(' '));
}

const root = process.argv[2];
for (const family_ of ['geometry', 'entropy', 'histogram']) {
  const dir = join(root, family_);
  for (const name of readdirSync(dir).filter((f) => f.endsWith('.json')).sort()) {
    const record = JSON.parse(readFileSync(join(dir, name)));
    if (!record.file) continue;
    const kind = family_ === 'geometry' ? 'geometry' : record.kind;
    const bytes = new Uint8Array(readFileSync(join(dir, record.file)));
    let line;
    try {
      line = { name: `${family_}/${record.file}`, ok: true, values: decode(kind, record, bytes) };
    } catch (err) {
      if (!(err instanceof FormatError)) throw err;
      line = { name: `${family_}/${record.file}`, ok: false, offset: err.offset, message: err.message };
    }
    process.stdout.write(`${JSON.stringify(line)}\n`);
  }
}
