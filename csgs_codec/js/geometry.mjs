/**
 * The geometry stream (spec/FORMAT.md §15): an octree of integer positions with direct-coded
 * isolated points, adaptive per-context tables and a repeat list for duplicates. Returns the
 * points in canonical (Morton) order as three Uint32Array coordinate arrays.
 */

import { FormatError } from './errors.mjs';
import { ByteReader } from './bytes.mjs';
import { RangeDecodeError, RangeDecoder, prepareTable } from './range_decoder.mjs';

const TOTAL = 65536;
const FIRST_BLOCK = 1024;
const POPCOUNT = Uint8Array.from({ length: 256 }, (_, v) => {
  let c = 0;
  for (let b = v; b; b >>= 1) c += b & 1;
  return c;
});

let frames = null;

/** OCC_CONTEXT (256 x 8) and FROM_FRAME (256 x 8 x 256) of §15.4.1, built once. */
function nodeFrames() {
  if (frames) return frames;
  const context = new Uint8Array(256 * 8);
  const fromFrame = new Uint8Array(256 * 8 * 256);
  const t = new Uint8Array(8);
  for (let occ = 0; occ < 256; occ++) {
    for (let k = 0; k < 8; k++) {
      const sib = [0, 1, 2].map((a) => (occ >> (k ^ (1 << a))) & 1);
      const order = [0, 1, 2].filter((a) => sib[a]).concat([0, 1, 2].filter((a) => !sib[a]));
      context[occ * 8 + k] = 4 * (sib[0] + sib[1] + sib[2]) + Math.min(Math.max(POPCOUNT[occ], 1), 4) - 1;
      for (let j = 0; j < 8; j++) {
        const m = j ^ k;
        t[j] = ((m >> order[0]) & 1) | (((m >> order[1]) & 1) << 1) | (((m >> order[2]) & 1) << 2);
      }
      // to_frame of every byte o, built from o without its lowest bit: O(1) per byte.
      const base = (occ * 8 + k) * 256;
      const toFrame = new Uint8Array(256);
      for (let o = 1; o < 256; o++) {
        const low = 31 - Math.clz32(o & -o);
        toFrame[o] = toFrame[o & (o - 1)] | (1 << t[low]);
        fromFrame[base + toFrame[o]] = o;
      }
    }
  }
  frames = { context, fromFrame };
  return frames;
}

/** Adaptive symbol counts per context (§15.5 "Counts"). */
class AdaptiveCounts {
  constructor(contexts, alphabet) {
    this.alphabet = alphabet;
    this.counts = new Float64Array(contexts * alphabet);
  }

  /** c - floor(c / 2) for every count: once per step. */
  age() {
    const c = this.counts;
    for (let i = 0; i < c.length; i++) c[i] -= Math.floor(c[i] / 2);
  }

  /** The prepared table of context ``ctx`` from the counts as they are (§15.5 "Frequencies"). */
  table(ctx) {
    const a = this.alphabet;
    const row = this.counts.subarray(ctx * a, ctx * a + a);
    let sum = 0;
    for (let s = 0; s < a; s++) sum += row[s];
    const effective = sum === 0 ? new Float64Array(a).fill(1) : row;
    if (sum === 0) sum = a;
    const freqs = new Float64Array(a);
    let total = 0;
    let best = 0;
    for (let s = 0; s < a; s++) {
      freqs[s] = 1 + Math.floor((effective[s] * (TOTAL - a)) / sum);
      total += freqs[s];
      if (effective[s] > effective[best]) best = s;
    }
    freqs[best] += TOTAL - total;
    return prepareTable(freqs, 8);
  }
}

/** Block ends of a step of m symbols (§15.5). */
function blockEnds(m) {
  const ends = [m];
  while (ends[ends.length - 1] > FIRST_BLOCK) ends.push(Math.floor(ends[ends.length - 1] / 2));
  return ends.reverse();
}

/** Decode one step's symbols (one per context entry) in blocks, grouped by context. */
function decodeGrouped(decoder, contexts, stats, nContexts) {
  const m = contexts.length;
  const out = new Uint8Array(m);
  const symbols = new Int32Array(Math.min(m, 1 << 20) || 1);
  const counts = new Int32Array(nContexts + 1);
  let order = new Int32Array(0);
  let start = 0;
  for (const end of blockEnds(m)) {
    // Positions of the block sorted by context (stable): a counting sort.
    counts.fill(0);
    for (let i = start; i < end; i++) counts[contexts[i] + 1]++;
    for (let c = 0; c < nContexts; c++) counts[c + 1] += counts[c];
    if (order.length < end - start) order = new Int32Array(end - start);
    const fill = counts.slice(0, nContexts);
    for (let i = start; i < end; i++) order[fill[contexts[i]]++] = i;
    let buffer = symbols;
    for (let c = 0; c < nContexts; c++) {
      const size = counts[c + 1] - counts[c];
      if (!size) continue;
      if (buffer.length < size) buffer = new Int32Array(size);
      decoder.decodeMany(stats.table(c), buffer, size);
      for (let j = 0; j < size; j++) out[order[counts[c] + j]] = buffer[j];
    }
    const a = stats.alphabet;
    for (let i = start; i < end; i++) stats.counts[contexts[i] * a + out[i]] += 1;
    start = end;
  }
  return out;
}

function geometryError(message, offset) {
  return new FormatError(`geometry: ${message}`, { offset });
}

/** Read one varint of the payload at ``pos``; returns [value, next position]. */
function readVarint(data, pos, what) {
  const r = new ByteReader(data.subarray(pos), pos);
  try {
    return [r.varint(what), r.offset];
  } catch (err) {
    throw geometryError(err.detail, err.offset);
  }
}

/** Read ``count`` varints for the repeat list (errors at the list's start, as §15.6 reads). */
function readVarints(data, pos, count, what) {
  const values = new Float64Array(count);
  let p = pos;
  for (let i = 0; i < count; i++) {
    let value = 0;
    let scale = 1;
    let length = 0;
    while (true) {
      if (p >= data.length) throw geometryError(`truncated varint list (${what})`, pos);
      const byte = data[p++];
      length++;
      value += (byte & 0x7f) * scale;
      scale *= 128;
      if (byte < 0x80) {
        if (length > 10) throw geometryError(`varint longer than 10 bytes (${what})`, pos);
        if (length === 10 && byte > 1) throw geometryError(`varint above 2^64 - 1 (${what})`, pos);
        if (length > 1 && byte === 0) throw geometryError(`varint not in shortest form (${what})`, pos);
        break;
      }
      if (length >= 10) throw geometryError(`varint longer than 10 bytes (${what})`, pos);
    }
    values[i] = value;
  }
  return [values, p];
}

/**
 * Decode a geometry payload.
 * @param {Uint8Array} data the payload
 * @param {number} maxPoints refuse more points than this
 * @returns {{x: Uint32Array, y: Uint32Array, z: Uint32Array, count: number}} positions in
 *   canonical order. Errors carry offsets relative to the payload start.
 */
export function decodeGeometry(data, maxPoints) {
  if (data.length < 2) throw geometryError('payload shorter than its 2-byte header', 0);
  if (data[0] !== 1) throw geometryError(`unknown version ${data[0]}`, 0);
  const bits = data[1];
  if (bits > 21) throw geometryError(`${bits} bits per axis exceeds 21`, 1);
  let [nPoints, pos] = readVarint(data, 2, 'point count');
  if (nPoints > maxPoints) throw geometryError(`${nPoints} points exceed the limit ${maxPoints}`, 2);
  if (nPoints === 0) {
    if (pos !== data.length) throw geometryError('trailing bytes after the payload', pos);
    return { x: new Uint32Array(0), y: new Uint32Array(0), z: new Uint32Array(0), count: 0 };
  }
  const [nDistinct, at] = readVarint(data, pos, 'distinct count');
  if (!(nDistinct >= 1 && nDistinct <= Math.min(nPoints, 2 ** (3 * bits)))) {
    throw geometryError(`distinct count ${nDistinct} out of range`, pos);
  }
  let counts = null;
  pos = at;
  if (nDistinct !== nPoints) [counts, pos] = readRepeats(data, pos, nPoints, nDistinct);
  const [nWords, wordsAt] = readVarint(data, pos, 'range-coder word count');
  if (nWords * 4 > data.length - wordsAt) throw geometryError('range-coder data runs past the payload', pos);
  const rawOffset = wordsAt + 4 * nWords;
  const decoder = new RangeDecoder(data.subarray(wordsAt, rawOffset), nWords);
  let points;
  try {
    points = decodeTree(decoder, data.subarray(rawOffset), rawOffset, bits, nDistinct);
  } catch (err) {
    if (err instanceof RangeDecodeError) throw geometryError(`range decoder failed (${err.message})`, null);
    throw err;
  }
  if (!counts) return points;
  const x = new Uint32Array(nPoints);
  const y = new Uint32Array(nPoints);
  const z = new Uint32Array(nPoints);
  let o = 0;
  for (let i = 0; i < nDistinct; i++) {
    for (let c = 0; c < counts[i]; c++) { x[o] = points.x[i]; y[o] = points.y[i]; z[o] = points.z[i]; o++; }
  }
  return { x, y, z, count: nPoints };
}

/** The repeat list (§15.6): per distinct position its number of occurrences. */
function readRepeats(data, pos, nPoints, nDistinct) {
  const [repeated, at] = readVarint(data, pos, 'repeat count');
  if (!(repeated >= 1 && repeated <= Math.min(nDistinct, nPoints - nDistinct))) {
    throw geometryError(`repeat count ${repeated} out of range`, pos);
  }
  const [gaps, at2] = readVarints(data, at, repeated, 'repeat gaps');
  const [extra, end] = readVarints(data, at2, repeated, 'repeat counts');
  let maxGap = 0;
  let maxExtra = 0;
  for (let i = 0; i < repeated; i++) { maxGap = Math.max(maxGap, gaps[i]); maxExtra = Math.max(maxExtra, extra[i]); }
  if (maxGap >= nDistinct || maxExtra >= nPoints) throw geometryError('repeat entry out of range', at);
  const counts = new Float64Array(nDistinct).fill(1);
  let index = -1;
  let sum = 0;
  const where = new Float64Array(repeated);
  for (let i = 0; i < repeated; i++) { index += gaps[i] + 1; where[i] = index; sum += extra[i]; }
  if (index >= nDistinct) throw geometryError('repeat index past the distinct points', at);
  if (sum + repeated !== nPoints - nDistinct) throw geometryError('repeat counts do not add up to the point count', at2);
  for (let i = 0; i < repeated; i++) counts[where[i]] += extra[i] + 1;
  return [counts, end];
}

/** The 3-bit group at bit ``bit`` of ``raw`` (MSB first; bits past the end read as 0). */
function triple(raw, bit) {
  const b = bit >> 3;
  const window = (raw[b] << 8) | (b + 1 < raw.length ? raw[b + 1] : 0);
  return (window >> (13 - (bit & 7))) & 7;
}

/**
 * Read a direct position's 3r-bit Morton field at bit ``start`` (§15.4 step 2): r groups of
 * (z, y, x) bits, most significant first; writes x, y, z low parts into out[0..2].
 */
function readDirect(raw, start, r, out) {
  let x = 0; let y = 0; let z = 0;
  let bit = start;
  for (let i = r - 1; i >= 0; i--, bit += 3) {
    const g = triple(raw, bit);
    z |= ((g >> 2) & 1) << i;
    y |= ((g >> 1) & 1) << i;
    x |= (g & 1) << i;
  }
  out[0] = x; out[1] = y; out[2] = z;
}

/** Decode the octree (§15.4); returns the D distinct positions in Morton order. */
function decodeTree(decoder, raw, rawOffset, bits, nDistinct) {
  const { context: OCC_CONTEXT, fromFrame: FROM_FRAME } = nodeFrames();
  const flagStats = new AdaptiveCounts(4, 2);
  const occStats = new AdaptiveCounts(17, 255);
  const levels = [];
  let nodes = { x: new Uint32Array(1), y: new Uint32Array(1), z: new Uint32Array(1),
    parentOcc: new Uint8Array(1), k: new Uint8Array(1), gpPop: new Uint8Array(1) };
  let nFound = 0;
  let rawBit = 0;
  for (let level = 0; level < bits; level++) {
    const r = bits - level;
    const m = nodes.x.length;
    const eligible = new Int32Array(m);
    let nEligible = 0;
    for (let i = 0; i < m; i++) if (level === 0 || POPCOUNT[nodes.parentOcc[i]] === 1) eligible[nEligible++] = i;
    const flagCtx = new Uint8Array(nEligible);
    for (let e = 0; e < nEligible; e++) {
      flagCtx[e] = level === 0 ? 0 : Math.min(Math.max(nodes.gpPop[eligible[e]], 1), 3);
    }
    flagStats.age();
    const flags = decodeGrouped(decoder, flagCtx, flagStats, 4);
    const direct = new Uint8Array(m);
    let nDirect = 0;
    for (let e = 0; e < nEligible; e++) if (flags[e] === 1) { direct[eligible[e]] = 1; nDirect++; }
    const record = { nodes, direct, dx: null, dy: null, dz: null, childStart: null, occ: null };
    if (nDirect) {
      const width = 3 * r;
      if (rawBit + nDirect * width > 8 * raw.length) {
        throw geometryError('raw position bits run past the payload', rawOffset + Math.floor(rawBit / 8));
      }
      record.dx = new Uint32Array(m); record.dy = new Uint32Array(m); record.dz = new Uint32Array(m);
      const low = new Uint32Array(3);
      const up = 2 ** r;
      for (let i = 0; i < m; i++) {
        if (!direct[i]) continue;
        readDirect(raw, rawBit, r, low);
        rawBit += width;
        // r <= 21 and the node's coordinates are below 2^(bits - r): the result is < 2^21.
        record.dx[i] = nodes.x[i] * up + low[0];
        record.dy[i] = nodes.y[i] * up + low[1];
        record.dz[i] = nodes.z[i] * up + low[2];
      }
      nFound += nDirect;
    }
    levels.push(record);
    const keep = new Int32Array(m - nDirect);
    let nKeep = 0;
    for (let i = 0; i < m; i++) if (!direct[i]) keep[nKeep++] = i;
    if (nKeep === 0) { nodes = null; break; }
    const occCtx = new Uint8Array(nKeep);
    const parentOcc = nodes.parentOcc;
    const ks = nodes.k;
    for (let j = 0; j < nKeep; j++) {
      const i = keep[j];
      occCtx[j] = level === 0 ? 16 : OCC_CONTEXT[parentOcc[i] * 8 + ks[i]];
    }
    occStats.age();
    const symbols = decodeGrouped(decoder, occCtx, occStats, 17);
    const occ = new Uint8Array(m);
    let nChildren = 0;
    for (let j = 0; j < nKeep; j++) {
      const i = keep[j];
      occ[i] = FROM_FRAME[(parentOcc[i] * 8 + ks[i]) * 256 + symbols[j] + 1];
      nChildren += POPCOUNT[occ[i]];
    }
    const next = { x: new Uint32Array(nChildren), y: new Uint32Array(nChildren), z: new Uint32Array(nChildren),
      parentOcc: new Uint8Array(nChildren), k: new Uint8Array(nChildren), gpPop: new Uint8Array(nChildren) };
    const childStart = new Int32Array(m);
    const { x: px, y: py, z: pz } = nodes;
    const { x: nx, y: ny, z: nz } = next;
    let c = 0;
    for (let i = 0; i < m; i++) {
      childStart[i] = c;
      if (direct[i]) continue;
      const o = occ[i];
      const x2 = px[i] * 2;
      const y2 = py[i] * 2;
      const z2 = pz[i] * 2;
      const gp = POPCOUNT[parentOcc[i]];
      for (let k = 0; k < 8; k++) {
        if (!(o & (1 << k))) continue;
        nx[c] = x2 + (k & 1);
        ny[c] = y2 + ((k >> 1) & 1);
        nz[c] = z2 + ((k >> 2) & 1);
        next.parentOcc[c] = o;
        next.k[c] = k;
        next.gpPop[c] = gp;
        c++;
      }
    }
    record.childStart = childStart;
    record.occ = occ;
    nodes = next;
    if (nFound + nChildren > nDistinct) throw geometryError('octree holds more points than the distinct count', rawOffset);
  }
  const leaves = nodes ? nodes.x.length : 0;
  if (nFound + leaves !== nDistinct) throw geometryError(`octree holds ${nFound + leaves} points, header says ${nDistinct}`, rawOffset);
  if (Math.floor((rawBit + 7) / 8) !== raw.length) throw geometryError('raw section length does not match its bits', rawOffset);
  if (rawBit % 8 && raw[raw.length - 1] & ((1 << (8 - (rawBit % 8))) - 1)) {
    throw geometryError('nonzero padding bits', rawOffset + raw.length - 1);
  }
  return canonicalOrder(levels, nodes, nDistinct);
}

/** Walk the recorded levels depth first: Morton order of the direct points and the leaves. */
function canonicalOrder(levels, leaves, count) {
  const x = new Uint32Array(count);
  const y = new Uint32Array(count);
  const z = new Uint32Array(count);
  let o = 0;
  const emit = (level, i) => {
    if (level === levels.length) { // a leaf of level B
      x[o] = leaves.x[i]; y[o] = leaves.y[i]; z[o] = leaves.z[i]; o++;
      return;
    }
    const rec = levels[level];
    if (rec.direct[i]) { x[o] = rec.dx[i]; y[o] = rec.dy[i]; z[o] = rec.dz[i]; o++; return; }
    const start = rec.childStart[i];
    const end = start + POPCOUNT[rec.occ[i]];
    for (let c = start; c < end; c++) emit(level + 1, c);
  };
  if (levels.length === 0) { // bits = 0: the root is the one position
    x[0] = 0; y[0] = 0; z[0] = 0;
    return { x, y, z, count };
  }
  const roots = levels[0].nodes.x.length;
  for (let i = 0; i < roots; i++) emit(0, i);
  return { x, y, z, count };
}
