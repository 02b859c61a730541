/** The semantic layer of a standard scene: SEMF or SEMC features and SEML or SEMR labels
 * (§12.16, §12.23, §12.17, §12.25). */

import { ByteReader } from './bytes.mjs';
import { decodeCategorical } from './categorical.mjs';
import { checkFinite, single } from './chunks.mjs';
import { FormatError } from './errors.mjs';
import { readFloatStream } from './float_stream.mjs';
import { decodeSymbols } from './residual.mjs';

/** A semantic channel name (§12.16): a PLY-safe identifier a 3DGS reader keeps as a semantic
 * channel. */
const SEMANTIC_NAME = /^(sem_|ins_feat_)[A-Za-z0-9_]+$/;

/** The semantic channel names of SEMF, SEMC and ASEM (§12.16, §17.11): count (at most
 * ``maximum``), then each name checked. */
export function readNames(r, maximum = 256) {
  const count = r.varint('channel_count', maximum);
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
  return names;
}

/** The value of an IEEE binary16 bit pattern (exact in a double, and in a float32). */
export function halfToFloat(bits) {
  const sign = bits & 0x8000 ? -1 : 1;
  const exponent = (bits >> 10) & 0x1f;
  const fraction = bits & 0x3ff;
  if (exponent === 0) return sign * fraction * 2 ** -24;
  if (exponent === 31) return fraction ? NaN : sign * Infinity;
  return sign * (1024 + fraction) * 2 ** (exponent - 25);
}

/** SEMC (§12.23): (names, N x S features), each Gaussian its instance's prototype. */
export function readCodebook(r, count) {
  const versionAt = r.offset;
  const version = r.u8('version');
  if (version !== 1) throw r.error(`SEMC version ${version} is not 1`, versionAt);
  const names = readNames(r);
  if (names.length === 0) throw r.error('a codebook needs at least one channel');
  const channels = names.length;
  let at = r.offset;
  const instances = r.varint('instance_count', 4294967296);
  if (!(instances >= 1 && instances <= 255)) throw r.error(`instance_count ${instances} is outside 1..255`, at);
  at = r.offset;
  const layout = r.u8('prototype_format');
  if (layout > 1) throw r.error(`prototype_format ${layout} is not 0 (float32) or 1 (float16)`, at);
  at = r.offset;
  const size = layout === 0 ? 4 : 2;
  const raw = r.raw(size * instances * channels, 'prototypes');
  const view = new DataView(raw.buffer, raw.byteOffset, raw.byteLength);
  const prototypes = new Float32Array(instances * channels);
  for (let i = 0; i < prototypes.length; i++) {
    prototypes[i] = layout === 0 ? view.getFloat32(4 * i, true) : halfToFloat(view.getUint16(2 * i, true));
    if (!Number.isFinite(prototypes[i])) throw r.error('a prototype value is not finite', at);
  }
  const rows = new Set();
  const bits = new Uint32Array(prototypes.buffer);
  for (let k = 0; k < instances; k++) {
    const key = bits.subarray(k * channels, (k + 1) * channels).join(',');
    if (rows.has(key)) throw r.error('two prototype rows are equal (each instance has its own)', at);
    rows.add(key);
  }
  at = r.offset;
  const width = r.varint('embedding_dim', 4294967296);
  if (width > 4096) throw r.error(`embedding_dim ${width} is above 4096`, at);
  let embeddings = null;
  if (width) {
    at = r.offset;
    const rawEmbeddings = r.raw(2 * instances * width, 'embeddings');
    const halves = new DataView(rawEmbeddings.buffer, rawEmbeddings.byteOffset, rawEmbeddings.byteLength);
    embeddings = new Float32Array(instances * width);
    for (let i = 0; i < embeddings.length; i++) {
      embeddings[i] = halfToFloat(halves.getUint16(2 * i, true));
      if (!Number.isFinite(embeddings[i])) throw r.error('an embedding value is not finite', at);
    }
  }
  const sameBytes = r.byteString('same_stream');
  const same = decodeCategorical(sameBytes, Math.max(count - 1, 0), r.chunk, r.offset - sameBytes.length, 2);
  let changes = 0;
  for (let i = 0; i < same.length; i++) if (same[i] === 0) changes++;
  const startCount = count === 0 ? 0 : 1 + changes;
  at = r.offset;
  const idBytes = r.byteString('id_stream');
  const starts = decodeCategorical(idBytes, startCount, r.chunk, r.offset - idBytes.length, Math.max(instances, 2));
  for (let i = 0; i < starts.length; i++) {
    if (starts[i] >= instances) throw r.error(`an instance id is not below instance_count ${instances}`, at);
  }
  r.expectEnd('the SEMC payload');
  const features = new Float32Array(count * channels);
  const ids = runsToSymbols(same, starts, count);
  for (let i = 0; i < count; i++) {
    features.set(prototypes.subarray(ids[i] * channels, (ids[i] + 1) * channels), i * channels);
  }
  return { names, features, instances: embeddings ? { prototypes, embeddings, width } : null, ids, instanceCount: instances };
}

/** The ``count`` symbols of a run coding (§12.23, §12.25): symbol 0 is ``starts[0]``; symbol i
 * repeats symbol i - 1 where ``same[i - 1]`` is 1, else it is the next unread start. */
function runsToSymbols(same, starts, count) {
  const out = new Uint8Array(count);
  let run = 0;
  for (let i = 0; i < count; i++) {
    if (i > 0 && same[i - 1] === 0) run++;
    out[i] = starts[run];
  }
  return out;
}

/** SEMR (§12.25): the ``count`` int32 labels, as runs of their own (source 0) or a label per
 * instance of the tile's SEMC (source 1; ``instances`` = { ids, instanceCount }, or null when
 * the tile has no SEMC). */
export function readLabelRuns(r, count, instances) {
  let at = r.offset;
  const version = r.u8('version');
  if (version !== 1) throw r.error(`SEMR version ${version} is not 1`, at);
  at = r.offset;
  const source = r.u8('source');
  if (source > 1) throw r.error(`source ${source} is not 0 (runs) or 1 (instances)`, at);
  if (source === 1 && !instances) throw r.error('source 1 (instances) in a tile without SEMC', at);
  at = r.offset;
  const valueCount = r.varint('value_count', 4294967296);
  if (source === 0 && !(valueCount >= 1 && valueCount <= 255)) throw r.error(`value_count ${valueCount} is outside 1..255`, at);
  if (source === 1 && valueCount !== instances.instanceCount) throw r.error(`value_count ${valueCount} is not the SEMC instance_count ${instances.instanceCount}`, at);
  const values = new Int32Array(valueCount);
  for (let k = 0; k < valueCount; k++) {
    at = r.offset;
    const v = r.svarintBig('value');
    if (v < -(2n ** 31n) || v >= 2n ** 31n) throw r.error('label outside the int32 range', at);
    values[k] = Number(v);
    if (source === 0 && k > 0 && values[k] <= values[k - 1]) throw r.error('values are not strictly increasing', at);
  }
  const labels = new Int32Array(count);
  if (source === 1) {
    r.expectEnd('the SEMR payload');
    for (let i = 0; i < count; i++) labels[i] = values[instances.ids[i]];
    return labels;
  }
  const sameBytes = r.byteString('same_stream');
  const same = decodeCategorical(sameBytes, Math.max(count - 1, 0), r.chunk, r.offset - sameBytes.length, 2);
  let changes = 0;
  for (let i = 0; i < same.length; i++) if (same[i] === 0) changes++;
  at = r.offset;
  const indexBytes = r.byteString('index_stream');
  const starts = decodeCategorical(indexBytes, count === 0 ? 0 : 1 + changes, r.chunk, r.offset - indexBytes.length, Math.max(valueCount, 2));
  for (let i = 0; i < starts.length; i++) {
    if (starts[i] >= valueCount) throw r.error(`an index is not below value_count ${valueCount}`, at);
  }
  r.expectEnd('the SEMR payload');
  const index = runsToSymbols(same, starts, count);
  for (let i = 0; i < count; i++) labels[i] = values[index[i]];
  return labels;
}

/** Decode SEMF or SEMC and SEML or SEMR when present into ``scene`` (semantic,
 * semanticNames, labels). */
export function decodeSemantic(container, header, scene, family) {
  const present = new Set(container.toc.entries.map((e) => e.type));
  let ids = null;
  if (present.has('SEMF')) {
    const [data, offset] = single(container, 'SEMF');
    const r = new ByteReader(data, offset, 'SEMF');
    const names = readNames(r);
    const values = readFloatStream(r, header.count, names.length, null, family);
    r.expectEnd('the semantic feature stream');
    checkFinite(values, 'SEMF');
    scene.semantic = values;
    scene.semanticNames = names;
  }
  if (present.has('SEMC')) {
    const [data, offset] = single(container, 'SEMC');
    if (present.has('SEMF')) throw new FormatError('a tile holds both SEMF and SEMC', { chunk: 'SEMC', offset });
    const codebook = readCodebook(new ByteReader(data, offset, 'SEMC'), header.count);
    scene.semantic = codebook.features;
    scene.semanticNames = codebook.names;
    scene.instances = codebook.instances;
    ids = { ids: codebook.ids, instanceCount: codebook.instanceCount };
  }
  const labels = readAnyLabels(container, header.count, family, ids);
  if (labels) scene.labels = labels;
}

/** The ``count`` int32 labels of the container's SEML or SEMR (a tile's Gaussians or an
 * anchor scene's anchors), or null when it holds neither; ``ids`` = { ids, instanceCount }
 * of the tile's SEMC, or null. */
export function readAnyLabels(container, count, family, ids = null) {
  const present = new Set(container.toc.entries.map((e) => e.type));
  if (present.has('SEMR')) {
    const [data, offset] = single(container, 'SEMR');
    if (present.has('SEML')) throw new FormatError('a tile holds both SEML and SEMR', { chunk: 'SEMR', offset });
    return readLabelRuns(new ByteReader(data, offset, 'SEMR'), count, ids);
  }
  return present.has('SEML') ? readLabels(container, count, family) : null;
}

/** The ``count`` int32 labels of the container's SEML (§12.17; a tile's Gaussians or an
 * anchor scene's anchors). */
export function readLabels(container, count, family) {
  const [data, offset] = single(container, 'SEML');
  const r = new ByteReader(data, offset, 'SEML');
  const base = r.svarintBig('label_base');
  const at = r.offset;
  const table = r.u8('scale_index');
  if (table >= 64) throw r.error(`scale index ${table} out of range`, at);
  const stream = r.byteString('label_stream');
  r.expectEnd('the label stream');
  const { values, big } = decodeSymbols(stream, table, count, family, 'SEML', r.offset - stream.length);
  const labels = new Int32Array(count);
  const exact = base >= -(2n ** 52n) && base <= 2n ** 52n;
  const baseNum = Number(base);
  for (let i = 0; i < values.length; i++) {
    let v;
    if (exact && !(big && big.has(i))) v = values[i] + baseNum;
    else v = Number((big && big.has(i) ? big.get(i) : BigInt(values[i])) + base);
    if (v < -(2 ** 31) || v >= 2 ** 31) throw r.error('label outside the int32 range');
    labels[i] = v;
  }
  return labels;
}
