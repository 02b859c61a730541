/**
 * Test helper: decodes single chunk payloads with the JavaScript receiver's modules. Reads a
 * JSON list of cases {"kind": "OUTQ" | "vdis" | "SEMC", "hex", "offset", "max"} from stdin and
 * prints one JSON line per case: {"ok": true, "float32": hex of the decoded positions'
 * little-endian bytes} for OUTQ, {"ok": true, "record": {...}} for vdis, {"ok": true,
 * "names": [...]} for SEMC ("max": its Gaussian count), or {"ok": false, "chunk", "offset"}
 * for a FormatError.
 * Usage: node payloads.mjs < cases.json
 */

import { readFileSync } from 'node:fs';

import { ByteReader } from '../../csgs_codec/js/bytes.mjs';
import { FormatError } from '../../csgs_codec/js/errors.mjs';
import { readFarPoints } from '../../csgs_codec/js/far_points.mjs';
import { readCodebook } from '../../csgs_codec/js/semantic_layer.mjs';
import { parseViewRecord } from '../../csgs_codec/js/view_record.mjs';

const hex = (bytes) => Buffer.from(bytes.buffer, bytes.byteOffset, bytes.byteLength).toString('hex');

for (const c of JSON.parse(readFileSync(0, 'utf8'))) {
  const data = Uint8Array.from(Buffer.from(c.hex, 'hex'));
  let result;
  try {
    if (c.kind === 'OUTQ') result = { ok: true, float32: hex(readFarPoints(data, c.offset, c.max)) };
    else if (c.kind === 'SEMC') result = { ok: true, names: readCodebook(new ByteReader(data, c.offset, 'SEMC'), c.max).names };
    else result = { ok: true, record: parseViewRecord(data, c.offset) };
  } catch (err) {
    if (!(err instanceof FormatError)) throw err;
    result = { ok: false, chunk: err.chunk, offset: err.offset };
  }
  process.stdout.write(`${JSON.stringify(result)}\n`);
}
