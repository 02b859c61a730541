/**
 * Test helper: the anchor decoder's exact integer steps on single inputs. Reads a JSON list of
 * cases from stdin and prints one JSON line per case:
 *
 *   {"kind": "values", "hex", "offset", "mean", "scale", "step"} -> decodeValues (per-value
 *     mean indices, scale and step indices): {"ok": true, "values": [decimal strings],
 *     "float32": hex of the float32 values}
 *   {"kind": "dense", "hex", "offset", "inputs": [[decimal strings]]} -> parseDenseNet and
 *     forwardDenseNet (kernel "js" or "wasm" as the case's "kernel" says): {"ok": true,
 *     "outputs": [[numbers]]}
 *
 * or {"ok": false, "chunk", "offset"} for a FormatError. Usage: node anchor_streams.mjs < cases.json
 */

import { readFileSync } from 'node:fs';

import { decodeValues, gridFloats } from '../../csgs_codec/js/anchor_attributes.mjs';
import { denseInputs, forwardDenseNet, parseDenseNet } from '../../csgs_codec/js/dense_net.mjs';
import { FormatError } from '../../csgs_codec/js/errors.mjs';
import { setIntNetKernel } from '../../csgs_codec/js/intnet.mjs';
import { loadTables } from '../../csgs_codec/js/tables_node.mjs';

const { family } = loadTables();
const hex = (typed) => Buffer.from(typed.buffer, typed.byteOffset, typed.byteLength).toString('hex');
/** A decimal string as a Number when exact, else a BigInt. */
const integer = (text) => { const v = BigInt(text); return v >= -(2n ** 53n) && v <= 2n ** 53n ? Number(v) : v; };

function run(c, data) {
  if (c.kind === 'values') {
    const p = { meanIndex: Float64Array.from(c.mean), scale: Float64Array.from(c.scale), step: Float64Array.from(c.step) };
    const { values, big } = decodeValues(data, p, family, 'AFEA', c.offset);
    const exact = Array.from(values, (v, i) => String(big && big.has(i) ? big.get(i) : BigInt(v)));
    return { ok: true, values: exact, float32: hex(gridFloats(values)) };
  }
  setIntNetKernel(c.kernel);
  const net = parseDenseNet(data, family, 'ACRM', c.offset);
  const rows = c.inputs.map((row) => row.map(integer));
  const out = forwardDenseNet(net, denseInputs(net, rows.length, (i, j) => rows[i][j]), rows.length);
  const width = net.outWidth;
  return { ok: true, outputs: rows.map((_, i) => Array.from(out.subarray(i * width, (i + 1) * width))) };
}

for (const c of JSON.parse(readFileSync(0, 'utf8'))) {
  let result;
  try {
    result = run(c, Uint8Array.from(Buffer.from(c.hex, 'hex')));
  } catch (err) {
    if (!(err instanceof FormatError)) throw err;
    result = { ok: false, chunk: err.chunk, offset: err.offset };
  }
  process.stdout.write(`${JSON.stringify(result)}\n`);
}
