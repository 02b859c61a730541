/**
 * Test helper: reads cases {freqs, counts, words} (JSON on stdin; words as u32 numbers),
 * decodes each with both range decoder loops (WebAssembly and JavaScript) and prints
 * {"wasm": [...symbols or "error"], "js": [...]} per case, one JSON line each.
 */

import { readFileSync } from 'node:fs';

import { JsRangeDecoder, RangeDecodeError, WasmRangeDecoder, prepareTable } from '../../csgs_codec/js/range_decoder.mjs';

function run(Decoder, kase) {
  const bytes = new Uint8Array(new Uint32Array(kase.words).buffer);
  const decoder = new Decoder(bytes, kase.words.length);
  const out = [];
  try {
    kase.groups.forEach(([freqs, count]) => {
      const symbols = new Int32Array(count);
      decoder.decodeMany(prepareTable(freqs), symbols, count);
      out.push(...symbols);
    });
  } catch (err) {
    if (!(err instanceof RangeDecodeError)) throw err;
    out.push('error');
  }
  return out;
}

for (const kase of JSON.parse(readFileSync(0, 'utf8'))) {
  process.stdout.write(`${JSON.stringify({ wasm: run(WasmRangeDecoder, kase), js: run(JsRangeDecoder, kase) })}\n`);
}
