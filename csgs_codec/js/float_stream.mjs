/**
 * Float stream bodies (spec/FORMAT.md §12.8): per channel a constant, or quantization indices
 * k coded with frozen tables, a histogram or the color hyperprior's per-Gaussian tables,
 * optionally predicted from the channels before it and with steps that follow scored classes
 * of decoded attributes (ROTN); values decode as float32((mu + q k) 2^-F).
 */

import { decodeHistogram } from './histogram.mjs';
import { decodeSymbols } from './residual.mjs';

const MAX_COUNT = 2 ** 28;
const COEF_LIMIT = 2n ** 15n;
const BIAS_LIMIT = 2n ** 40n;
const INDEX_LIMIT = 2 ** 31;
const TWO53 = 2 ** 53;

/** Integer step q of step index j (§16.3.1). */
export function stepSize(j) {
  const m = j + 1;
  return m < 16 ? m : (8 + (m % 8)) * 2 ** (Math.floor(m / 8) - 1);
}

/**
 * Prediction P_i = floor((sum_j A_j k_j,i + B) / 2^12) for all i, exact: float64 when the
 * worst-case sum stays within 2^53, BigInt otherwise.
 */
function predict(indices, peaks, coefs, bias, n) {
  let bound = Math.abs(Number(bias));
  coefs.forEach((a, j) => { bound += Math.abs(Number(a)) * peaks[j]; });
  const out = new Float64Array(n);
  if (bound <= TWO53) {
    const b = Number(bias);
    const active = [];
    for (let j = 0; j < coefs.length; j++) if (coefs[j]) active.push([Number(coefs[j]), indices[j]]);
    // Rows in blocks, so the block of ``out`` stays in cache while every channel adds to it;
    // four channels per pass (integer sums within 2^53 are exact in any order).
    for (let start = 0; start < n; start += 4096) {
      const end = Math.min(n, start + 4096);
      for (let i = start; i < end; i++) out[i] = b;
      let j = 0;
      for (; j + 4 <= active.length; j += 4) {
        const [a0, k0] = active[j];
        const [a1, k1] = active[j + 1];
        const [a2, k2] = active[j + 2];
        const [a3, k3] = active[j + 3];
        for (let i = start; i < end; i++) out[i] += a0 * k0[i] + a1 * k1[i] + a2 * k2[i] + a3 * k3[i];
      }
      for (; j < active.length; j++) {
        const [a, k] = active[j];
        for (let i = start; i < end; i++) out[i] += a * k[i];
      }
      for (let i = start; i < end; i++) out[i] = Math.floor(out[i] * (1 / 4096));
    }
    return out;
  }
  for (let i = 0; i < n; i++) {
    let total = bias;
    coefs.forEach((a, j) => { total += a * BigInt(indices[j][i]); });
    out[i] = Number(total >> 12n);
  }
  return out;
}

/** Table sources (bits 0-1 of a channel record's ``coding``) and its flags (§12.8). */
const TABLE_CONSTANT = 0;
const TABLE_FROZEN = 1;
const TABLE_HISTOGRAM = 2;
const TABLE_PRIOR = 3;
const PREDICTED_FLAG = 0x10;
const SCORED_FLAG = 0x20;
const RESERVED_BITS = 0xff & ~(0x03 | PREDICTED_FLAG | SCORED_FLAG);
const TABLE_NAMES = ['constant', 'frozen', 'histogram', 'hyperprior'];

/** Read and check channel c's ``coding`` byte: {table, predicted, scored}. */
function readCoding(r, c) {
  const at = r.offset;
  const byte = r.u8('coding');
  const coding = { table: byte & 0x03, predicted: (byte & PREDICTED_FLAG) !== 0, scored: (byte & SCORED_FLAG) !== 0 };
  let why = null;
  if (byte & RESERVED_BITS) why = `coding 0x${byte.toString(16).padStart(2, '0')} sets reserved bits`;
  else if (coding.table === TABLE_CONSTANT && (coding.predicted || coding.scored)) why = 'a constant channel is neither predicted nor scored';
  else if (coding.scored && coding.table !== TABLE_FROZEN) why = `scored steps with ${TABLE_NAMES[coding.table]} tables (frozen only)`;
  if (why) throw r.error(`channel ${c}: ${why}`, at);
  return coding;
}

/**
 * The coder of each table source: its fields after the step (and score table), and how it
 * decodes the residual stream (§12.8, §16.3.3, §16.5, §12.19).
 */
const CODERS = {
  [TABLE_FROZEN]: {
    readFields(r, c, context) {
      const tables = [];
      for (let a = 0; a < context.classCount; a++) tables.push(r.u8('scale_index'));
      if (tables.some((t) => t >= 64)) throw r.error(`channel ${c}: scale index out of range`);
      return tables;
    },
    decode(stream, tables, context, family, chunk, at) {
      if (!context.classes) return decodeSymbols(stream, tables[0], context.n, family, chunk, at);
      const perValue = new Uint8Array(context.n);
      for (let i = 0; i < context.n; i++) perValue[i] = tables[context.classes[i]];
      return decodeSymbols(stream, perValue, context.n, family, chunk, at);
    },
  },
  [TABLE_HISTOGRAM]: {
    readFields() { return null; },
    decode(stream, fields, context, family, chunk, at) { return decodeHistogram(stream, context.n, chunk, at); },
  },
  [TABLE_PRIOR]: {
    readFields(r, c, context) {
      if (!context.prior) throw r.error(`channel ${c} uses the color hyperprior, which does not model it`);
      return null;
    },
    decode(stream, fields, context, family, chunk, at) { return decodeSymbols(stream, context.prior.scale, context.n, family, chunk, at); },
  },
};

/**
 * Read a float stream body.
 * @param {import('./bytes.mjs').ByteReader} r positioned at the body
 * @param {number} count N the chunk expects
 * @param {number} channels C the chunk expects
 * @param {Map<number, {mean: Float64Array, scale: Uint8Array}>|null} priors the color
 *   hyperprior's per-Gaussian mean and table of the channels it models
 * @param {object} family the Gaussian tables
 * @param {{array: Float32Array, stride: number, offset: number}|null} target where value i
 *   of channel c goes: array[i * stride + offset + c] (default: a new N x C array)
 * @param {{logScales: () => Float32Array, opacity: () => Float32Array}|null} attributes
 *   return the decoded log-scales (N x 3) and opacity logits (N) that channels with scored
 *   steps derive their steps from; null where scored steps are not allowed (not ROTN)
 * @returns {Float32Array} the target array
 */
export function readFloatStream(r, count, channels, priors, family, target = null, attributes = null) {
  const n = r.varint('count', MAX_COUNT);
  if (n !== count) throw r.error(`stream holds ${n} values, the scene has ${count} Gaussians`);
  const cCount = r.u8('channel_count');
  if (cCount !== channels) throw r.error(`stream has ${cCount} channels, expected ${channels}`);
  const f = r.u8('frac_bits');
  if (f > 24) throw r.error(`frac_bits ${f} exceeds 24`);
  const unit = 2 ** -f;
  const { array, stride, offset } = target || { array: new Float32Array(n * cCount), stride: cCount, offset: 0 };
  const steps = [];
  const indices = [];
  const peaks = [];
  let peak = 0;
  const classCache = new Map(); // channels with one score table share its classes
  for (let c = 0; c < cCount; c++) {
    const coding = readCoding(r, c);
    if (coding.table === TABLE_CONSTANT) {
      steps.push({ constant: r.f32('constant_value') });
      indices.push(new Int32Array(n));
      peaks.push(0);
      continue;
    }
    if (coding.scored && !attributes) throw r.error(`channel ${c}: scored steps are only allowed in ROTN`);
    const mean = r.svarintBig('mean');
    const step = r.u8('step_index');
    if ((mean < 0n ? -mean : mean) > 2n ** 53n || step >= 176) throw r.error(`channel ${c}: mean or step index out of range`);
    const scoreTable = coding.scored ? readScoreTable(r, c, n, step, attributes, classCache) : null;
    const context = {
      n,
      classes: scoreTable ? scoreTable.classes : null,
      classCount: scoreTable ? scoreTable.offsets.length : 1,
      prior: coding.table === TABLE_PRIOR && priors ? priors.get(c) : undefined,
    };
    const coder = CODERS[coding.table];
    const fields = coder.readFields(r, c, context);
    const prediction = coding.predicted ? readPrediction(r, c, c, indices, peaks, peak, n) : null;
    const stream = r.byteString('residual_stream');
    const decoded = coder.decode(stream, fields, context, family, r.chunk, r.offset - stream.length);
    const k = decoded.values;
    const priorMean = context.prior ? context.prior.mean : null;
    const meanNum = Number(mean);
    const room = TWO53 - Math.abs(meanNum);
    const limitOf = (q) => {
      let limit = Math.floor(room / q);
      if (limit * q > room) limit -= 1; // floor of the exact quotient
      return limit;
    };
    const stepOf = scoreTable ? scoreTable.offsets.map((o) => stepSize(step + o)) : null;
    const qs = scoreTable ? new Float64Array(n) : null;
    const q = stepSize(step);
    // k as int32 too (exact whenever |k| < 2^31, the only case a later prediction reads it).
    const k32 = new Int32Array(n);
    let top = 0;
    let over = false;
    for (let i = 0; i < n; i++) {
      let v = k[i];
      if (priorMean) v += priorMean[i];
      if (prediction) v += prediction[i];
      k[i] = v;
      k32[i] = v;
      const a = Math.abs(v);
      if (a > top) top = a;
      if (qs) {
        const qi = stepOf[scoreTable.classes[i]];
        qs[i] = qi;
        if (a > limitOf(qi)) over = true;
      }
    }
    if (decoded.big) {
      for (const [i, s] of decoded.big) {
        const exact = s + BigInt((priorMean ? priorMean[i] : 0) + (prediction ? prediction[i] : 0));
        const a = exact < 0n ? -exact : exact;
        k[i] = Number(exact);
        if (a > 2n ** 53n) top = Infinity;
        else if (Number(a) > top) top = Number(a);
        if (qs && a * BigInt(qs[i]) > BigInt(room)) over = true;
      }
    }
    if (over || (!qs && top > limitOf(q))) throw r.error(`channel ${c}: decoded value exceeds 2^53 on its grid`);
    if (top > peak) peak = top;
    steps.push(qs ? { qs, mean: meanNum } : { q, mean: meanNum });
    indices.push(top < INDEX_LIMIT ? k32 : k);
    peaks.push(top);
  }
  writeValues(array, stride, offset, indices, steps, unit, n);
  return array;
}

/** Write value i of channel c, float32((mu + q k) 2^-F), to array[i * stride + offset + c],
 * rows in blocks so that a block of interleaved rows stays in cache across the channels. */
function writeValues(array, stride, offset, indices, steps, unit, n) {
  for (let start = 0; start < n; start += 2048) {
    const end = Math.min(n, start + 2048);
    for (let c = 0; c < steps.length; c++) {
      const step = steps[c];
      let at = start * stride + offset + c;
      if (step.constant !== undefined) {
        for (let i = start; i < end; i++, at += stride) array[at] = step.constant;
        continue;
      }
      const { q, qs, mean } = step;
      const k = indices[c];
      if (qs) {
        for (let i = start; i < end; i++, at += stride) array[at] = (k[i] * qs[i] + mean) * unit;
        continue;
      }
      for (let i = start; i < end; i++, at += stride) array[at] = (k[i] * q + mean) * unit;
    }
  }
}

/** The channel prediction of §12.8 (m integer coefficients on the earlier channels' indices,
 * and a bias), checked against the coefficient and index limits; returns the (n) predictions. */
function readPrediction(r, c, m, indices, peaks, peak, n) {
  const coefs = [];
  for (let j = 0; j < m; j++) coefs.push(r.svarintBig('coefficient'));
  const bias = r.svarintBig('bias');
  const abs = (v) => (v < 0n ? -v : v);
  if (coefs.some((a) => abs(a) >= COEF_LIMIT) || abs(bias) >= BIAS_LIMIT) {
    throw r.error(`channel ${c}: prediction coefficient out of range`);
  }
  if (peak >= INDEX_LIMIT) throw r.error(`channel ${c}: earlier indices too large to predict from`);
  return predict(indices, peaks, coefs, bias, n);
}

/** cache.get(key), computed by make() the first time. */
function cached(cache, key, make) {
  if (!cache.has(key)) cache.set(key, make());
  return cache.get(key);
}

/** Number of thresholds at or below x (thresholds increasing). */
function binOf(thresholds, x) {
  let b = 0;
  while (b < thresholds.length && thresholds[b] <= x) b++;
  return b;
}

/** Scored cell of every Gaussian: bin_u * K_v + bin_v, each score
 * ((w0 S0 + w1 S1) + w2 S2) + w3 min(O, 0) of its log-scales sorted largest first and its
 * opacity logit, in binary64 (the products are exact on float32 inputs). */
function scoredClasses(weights, tu, tv, scales, opacity, n) {
  const classes = new Uint8Array(n);
  const kv = tv.length + 1;
  const [u, v] = [weights.slice(0, 4), weights.slice(4)];
  for (let i = 0; i < n; i++) {
    let a = scales[3 * i];
    let b = scales[3 * i + 1];
    let c = scales[3 * i + 2];
    if (a < b) [a, b] = [b, a];
    if (b < c) [b, c] = [c, b];
    if (a < b) [a, b] = [b, a];
    const o = Math.min(opacity[i], 0);
    const su = ((u[0] * a + u[1] * b) + u[2] * c) + u[3] * o;
    const sv = ((v[0] * a + v[1] * b) + v[2] * c) + v[3] * o;
    classes[i] = binOf(tu, su) * kv + binOf(tv, sv);
  }
  return classes;
}

/**
 * A channel's scored-step table (§12.8), the reader at its first weight: the class of every
 * Gaussian, a cell of two scores of its decoded log-scales and opacity, and each class's
 * step offset.
 * @returns {{classes: Uint8Array, offsets: number[]}}
 */
function readScoreTable(r, c, n, step, attributes, classCache) {
  const at = r.offset;
  const weights = [];
  for (let a = 0; a < 8; a++) weights.push(r.f32('score_weight'));
  const bins = [];
  for (const name of ['u', 'v']) {
    const count = r.u8(`bin_count_${name}`);
    if (count < 1 || count > 8) throw r.error(`channel ${c}: ${count} bins of score ${name}, outside 1..8`);
    const t = [];
    for (let a = 0; a + 1 < count; a++) t.push(r.f32(`threshold_${name}`));
    bins.push(t);
  }
  const classCount = (bins[0].length + 1) * (bins[1].length + 1);
  const offsets = [];
  for (let a = 0; a < classCount; a++) offsets.push(Number(r.svarintBig('step_offset')));
  if (!weights.every(Number.isFinite)) throw r.error(`channel ${c}: score weights must be finite`, at);
  for (const [name, t] of [['u', bins[0]], ['v', bins[1]]]) {
    const increasing = t.every((x, a) => Number.isFinite(x) && (a === 0 || x > t[a - 1]));
    if (!increasing) throw r.error(`channel ${c}: thresholds of score ${name} must be finite and strictly increasing`, at);
  }
  if (offsets.some((o) => step + o < 0 || step + o >= 176)) throw r.error(`channel ${c}: step index ${step} plus offsets [${offsets}] leaves [0, 176)`, at);
  const key = `${weights}:${bins[0]}:${bins[1]}`;
  const classes = cached(classCache, key, () => scoredClasses(weights, bins[0], bins[1], attributes.logScales(), attributes.opacity(), n));
  return { classes, offsets };
}
