/**
 * The color hyperprior chunk CHYP (spec/FORMAT.md §12.19): a channel mask over the color
 * streams and an integer network whose outputs give each modelled channel a per-Gaussian
 * mean (in steps) and scale-table index. The network runs in decode_tasks.mjs (PRIOR tasks).
 */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';
import { parseIntNet } from './intnet.mjs';

export const STREAM_CHANNELS = { SHDC: 3, SHBA: 9, SHBB: 15, SHBC: 21, OPAC: 1, SCAL: 3, ROTN: 3 };

/**
 * Parse a CHYP payload for the color streams ``codes`` and a grid of ``posBits``.
 * @returns {{mask: Uint8Array, net: object}}
 */
export function parseColorPrior(bytes, baseOffset, codes, posBits, family) {
  const r = new ByteReader(bytes, baseOffset, 'CHYP');
  const version = r.u8('version');
  if (version !== 1) throw r.error(`color hyperprior version ${version} is not 1`, baseOffset);
  const total = codes.reduce((sum, code) => sum + STREAM_CHANNELS[code], 0);
  const count = r.varint('channel_count', 65536);
  if (count !== total) throw r.error(`the mask covers ${count} channels, the color streams have ${total}`);
  const packed = r.raw(Math.ceil(total / 8), 'channel_mask');
  const mask = new Uint8Array(total);
  for (let i = 0; i < 8 * packed.length; i++) {
    const bit = (packed[i >> 3] >> (i & 7)) & 1;
    if (i < total) mask[i] = bit;
    else if (bit) throw r.error('channel mask has bits set beyond the channel count');
  }
  const netAt = r.offset;
  const net = parseIntNet(bytes.subarray(r.pos), family, 'CHYP', netAt);
  const m = mask.reduce((a, b) => a + b, 0);
  const outWidth = net.layers[net.layers.length - 1].out;
  if (outWidth !== 2 * m) {
    throw new FormatError(`network has ${outWidth} outputs, the mask models ${m} channels`, { chunk: 'CHYP', offset: netAt });
  }
  const MEAN_LIMIT = 2 ** 40;
  for (let o = 0; o < outWidth; o++) {
    const bad = o < m
      ? Math.abs(net.lo[o]) > MEAN_LIMIT || Math.abs(net.hi[o]) > MEAN_LIMIT
      : net.lo[o] < 0 || net.hi[o] > 63;
    if (bad) throw new FormatError('network output clamps out of range', { chunk: 'CHYP', offset: netAt });
  }
  if (net.posBits !== posBits) {
    throw new FormatError(`network pos_bits ${net.posBits} differs from the grid's ${posBits}`, { chunk: 'CHYP', offset: netAt });
  }
  return { mask, net };
}

/** The streams (chunk codes) among ``codes`` with a modelled channel. */
export function modelledStreams(prior, codes) {
  const out = new Set();
  let t = 0;
  for (const code of codes) {
    for (let c = 0; c < STREAM_CHANNELS[code]; c++, t++) if (prior.mask[t]) out.add(code);
  }
  return out;
}
