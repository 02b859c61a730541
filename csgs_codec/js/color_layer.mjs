/**
 * The color layer of a standard scene: the float streams SHDC, SHB*, OPAC, SCAL and ROTN
 * (§12.8-§12.15) written into interleaved output arrays, SH bands in opponent colours turned
 * back into colours (SHXF, §12.24), and the rotations (§12.4).
 */

import { ByteReader } from './bytes.mjs';
import { decodeCategorical } from './categorical.mjs';
import { single } from './chunks.mjs';
import { STREAM_CHANNELS } from './color_prior.mjs';
import { FormatError } from './errors.mjs';
import { readFloatStream } from './float_stream.mjs';

export const BAND_CODES = ['SHBA', 'SHBB', 'SHBC'];
export const SH_REST = [0, 3, 8, 15];
const SQRT2 = Math.fround(Math.SQRT2);

/** FormatError when a stream's channels in ``target`` hold a non-finite value. */
function checkTarget(target, channels, n, chunk) {
  const { array, stride, offset } = target;
  for (let i = 0; i < n; i++) {
    const row = i * stride + offset;
    for (let c = 0; c < channels; c++) {
      if (!Number.isFinite(array[row + c])) throw new FormatError('decoded values overflow float32', { chunk });
    }
  }
}

// The inverse colour transform's binary64 constants (§12.24).
const XF_A = 0.5773502691896258; // 0x1.279a74590331dp-1
const XF_B = 0.7071067811865475; // 0x1.6a09e667f3bccp-1
const XF_C = 0.4082482904638631; // 0x1.a20bd700c2c3fp-2
const XF_D = 0.8164965809277261; // 0x1.a20bd700c2c3fp-1

/** The SHXF record (§12.24): one transform id per coded band (0 colours, 1 opponent). */
export function readShTransforms(container, coded) {
  const [data, offset] = single(container, 'SHXF');
  const r = new ByteReader(data, offset, 'SHXF');
  let at = r.offset;
  const version = r.u8('version');
  if (version !== 1) throw r.error(`unsupported SH colour transform version ${version}`, at);
  at = r.offset;
  const count = r.u8('band_count');
  if (count !== coded || count === 0) throw r.error(`the record lists ${count} bands, the scene codes ${coded}`, at);
  const transforms = [];
  for (let b = 0; b < count; b++) {
    at = r.offset;
    const t = r.u8('transform');
    if (t > 1) throw r.error(`unknown SH colour transform ${t}`, at);
    transforms.push(t);
  }
  r.expectEnd('the SH colour transform record');
  return { transforms, offset };
}

/** Opponent values of one band in ``target`` (N rows of ``channels``) turned into colours in
 * place, in binary64 in the order §12.24 fixes, each result rounded once to float32. */
function inverseShTransform(target, channels, n, band, offset) {
  const { array, stride, offset: first } = target;
  for (let i = 0; i < n; i++) {
    const row = i * stride + first;
    for (let c = 0; c < channels; c += 3) {
      const y0 = array[row + c];
      const y1 = array[row + c + 1];
      const y2 = array[row + c + 2];
      const a0 = XF_A * y0;
      const b1 = XF_B * y1;
      const c2 = XF_C * y2;
      const r = Math.fround((a0 + b1) + c2);
      const g = Math.fround(a0 - XF_D * y2);
      const b = Math.fround((a0 - b1) + c2);
      if (!Number.isFinite(r) || !Number.isFinite(g) || !Number.isFinite(b)) {
        throw new FormatError(`SH band ${band}'s colours overflow float32`, { chunk: 'SHXF', offset });
      }
      array[row + c] = r;
      array[row + c + 1] = g;
      array[row + c + 2] = b;
    }
  }
}

/** One color stream, its values written into ``target`` (and for ROTN the dropped-component
 * indices returned); ``attributes`` (ROTN) = {logScales, opacity}, functions returning the
 * decoded SCAL and OPAC values scored steps read; ``shTransforms`` the SHXF record or null. */
export function decodeStream(container, header, code, priors, family, target, attributes = null, shTransforms = null) {
  const [data, offset] = single(container, code);
  const r = new ByteReader(data, offset, code);
  let axis = null;
  if (code === 'ROTN') {
    const stream = r.byteString('axis_stream');
    axis = decodeCategorical(stream, header.count, code, r.offset - stream.length);
    for (let i = 0; i < axis.length; i++) if (axis[i] > 3) throw r.error('dropped-component index above 3');
  }
  readFloatStream(r, header.count, STREAM_CHANNELS[code], priors, family, target, code === 'ROTN' ? attributes : null);
  r.expectEnd(`the ${code} stream`);
  checkTarget(target, STREAM_CHANNELS[code], header.count, code);
  const band = BAND_CODES.indexOf(code) + 1;
  if (band > 0 && shTransforms && shTransforms.transforms[band - 1] === 1) {
    inverseShTransform(target, STREAM_CHANNELS[code], header.count, band, shTransforms.offset);
  }
  return axis;
}

/** (w, x, y, z) float32 quaternions from the smallest three, N x 3 (§12.4 "rotation"). */
export function rotations(axis, rest, n) {
  const out = new Float32Array(4 * n);
  const t = new Float32Array(3);
  for (let i = 0; i < n; i++) {
    const t0 = Math.fround(rest[3 * i] / SQRT2);
    const t1 = Math.fround(rest[3 * i + 1] / SQRT2);
    const t2 = Math.fround(rest[3 * i + 2] / SQRT2);
    const sum = Math.fround(Math.fround(Math.fround(t0 * t0) + Math.fround(t1 * t1)) + Math.fround(t2 * t2));
    const m = Math.fround(1 - sum);
    const big = Math.fround(Math.sqrt(Math.max(m, 0)));
    const d = axis[i];
    t[0] = t0; t[1] = t1; t[2] = t2;
    let j = 0;
    for (let a = 0; a < 4; a++) out[4 * i + a] = a === d ? big : t[j++];
  }
  return out;
}
