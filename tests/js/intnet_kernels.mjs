/**
 * Test helper: reads cases {payload (hex), positions [[x, y, z], ...]} as JSON on stdin,
 * evaluates each network (intnet.mjs parseIntNet) on its positions with both kernels
 * (WebAssembly SIMD and the scalar JavaScript loop) and prints one JSON line per case:
 * {"wasm": [[...outputs as decimal strings]], "js": [...], "simd": bool} ("simd": whether the
 * WebAssembly kernel exists here).
 */

import { readFileSync } from 'node:fs';

import { forwardIntNet, parseIntNet, setIntNetKernel } from '../../csgs_codec/js/intnet.mjs';
import { loadTables } from '../../csgs_codec/js/tables_node.mjs';
import { denseInstance } from '../../csgs_codec/js/wasm_intnet.mjs';

const { family, sine } = loadTables();

function run(kernel, net, positions) {
  setIntNetKernel(kernel);
  const cols = [0, 1, 2].map((d) => Float64Array.from(positions, (p) => p[d]));
  const out = forwardIntNet(net, cols[0], cols[1], cols[2], positions.length, sine);
  const width = out.length / Math.max(positions.length, 1);
  // Object.is keeps -0 apart from 0: the kernels must agree on the sign of a zero too.
  return positions.map((_, i) => Array.from(out.subarray(i * width, (i + 1) * width), (v) => (Object.is(v, -0) ? '-0' : String(v))));
}

for (const kase of JSON.parse(readFileSync(0, 'utf8'))) {
  const bytes = Uint8Array.from(Buffer.from(kase.payload, 'hex'));
  const net = parseIntNet(bytes, family, null, 0);
  const line = { wasm: run('wasm', net, kase.positions), js: run('js', net, kase.positions), simd: denseInstance() !== null };
  process.stdout.write(`${JSON.stringify(line)}\n`);
}
