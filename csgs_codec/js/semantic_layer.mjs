/** The semantic layer of a standard scene: SEMF features and SEML labels (§12.16, §12.17). */

import { ByteReader } from './bytes.mjs';
import { checkFinite, single } from './chunks.mjs';
import { readFloatStream } from './float_stream.mjs';
import { decodeSymbols } from './residual.mjs';

/** A semantic channel name (§12.16): a PLY-safe identifier a 3DGS reader keeps as a semantic
 * channel. */
const SEMANTIC_NAME = /^(sem_|ins_feat_)[A-Za-z0-9_]+$/;

/** Decode SEMF and SEML when present into ``scene`` (semantic, semanticNames, labels). */
export function decodeSemantic(container, header, scene, family) {
  const present = new Set(container.toc.entries.map((e) => e.type));
  if (present.has('SEMF')) {
    const [data, offset] = single(container, 'SEMF');
    const r = new ByteReader(data, offset, 'SEMF');
    const count = r.varint('channel_count', 256);
    const names = [];
    const decoder = new TextDecoder('utf-8', { fatal: true });
    for (let i = 0; i < count; i++) {
      const at = r.offset;
      const raw = r.byteString('channel_name', 256);
      let name;
      try { name = decoder.decode(raw); } catch { throw r.error('channel name is not UTF-8'); }
      if (!SEMANTIC_NAME.test(name)) throw r.error(`semantic channel name ${JSON.stringify(name)} is not a PLY-safe semantic identifier (sem_ or ins_feat_ followed by ASCII letters, digits or underscores)`, at);
      if (names.includes(name)) throw r.error(`semantic channel name ${JSON.stringify(name)} appears twice`, at);
      names.push(name);
    }
    const values = readFloatStream(r, header.count, names.length, null, family);
    r.expectEnd('the semantic feature stream');
    checkFinite(values, 'SEMF');
    scene.semantic = values;
    scene.semanticNames = names;
  }
  if (present.has('SEML')) {
    const [data, offset] = single(container, 'SEML');
    const r = new ByteReader(data, offset, 'SEML');
    const base = r.svarintBig('label_base');
    const table = r.u8('scale_index');
    const stream = r.byteString('label_stream');
    r.expectEnd('the label stream');
    if (table >= 64) throw r.error(`scale index ${table} out of range`);
    const { values, big } = decodeSymbols(stream, table, header.count, family, 'SEML', r.offset - stream.length);
    const labels = new Int32Array(header.count);
    const exact = base >= -(2n ** 52n) && base <= 2n ** 52n;
    const baseNum = Number(base);
    for (let i = 0; i < values.length; i++) {
      let v;
      if (exact && !(big && big.has(i))) v = values[i] + baseNum;
      else v = Number((big && big.has(i) ? big.get(i) : BigInt(values[i])) + base);
      if (v < -(2 ** 31) || v >= 2 ** 31) throw r.error('label outside the int32 range');
      labels[i] = v;
    }
    scene.labels = labels;
  }
}
