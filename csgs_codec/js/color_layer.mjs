/**
 * The color layer of a standard scene: the float streams SHDC, SHB*, OPAC, SCAL and ROTN
 * (§12.8-§12.15) written into interleaved output arrays, and the rotations (§12.4).
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

/** One color stream, its values written into ``target`` (and for ROTN the dropped-component
 * indices returned); ``attributes`` (ROTN) = {logScales, opacity}, functions returning the
 * decoded SCAL and OPAC values modes 6 and 7 read. */
export function decodeStream(container, header, code, priors, family, target, attributes = null) {
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
