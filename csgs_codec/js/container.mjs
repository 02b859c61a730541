/**
 * The .csgs container (spec/FORMAT.md §3-§8, §10): header, table of contents with its CRC,
 * chunk frames with theirs. Reads only the layers asked for: a color-only read never touches
 * a byte of the semantic layer.
 */

import { ByteReader } from './bytes.mjs';
import { crc32 } from './crc32.mjs';
import { FormatError } from './errors.mjs';

const MAGIC = [0x89, 0x43, 0x53, 0x47, 0x0d, 0x0a, 0x1a, 0x0a];
const HEADER_SIZE = 16;
const MAX_TOC_SIZE = 4194304;
const MAX_CHUNKS = 65535;
const MAX_U32 = 4294967295;
const FRAME_OVERHEAD = 12;
export const LAYERS = ['base', 'color', 'semantic'];

/** Registered chunk types and their layer (§12.1); 'fill' may be in any layer. */
export const CHUNK_LAYERS = {
  fill: null, TIDX: 0, SCNE: 0, GEOM: 0, OUTL: 0, OUTQ: 0, vdis: 0, CHYP: 1, SHDC: 1, SHBA: 1,
  SHBB: 1, SHBC: 1, SHXF: 1, OPAC: 1, SCAL: 1, ROTN: 1, SEMF: 2, SEML: 2, SEMC: 2, SEMR: 2, ANCH: 0, AHYP: 0, ACRM: 0,
  AMSK: 0, AMLP: 0, vorg: 0, AFEA: 1, AOFF: 1, ASCL: 1, SHYP: 2, ASEM: 2,
};

function isLetter(b) { return (b >= 65 && b <= 90) || (b >= 97 && b <= 122); }

/**
 * Parse and check the header and TOC (§4, §5, §8 steps 1-5).
 * @param {Uint8Array} data the file, or a prefix of it
 * @returns {{major:number, minor:number, flags:number, entries:object[], tocEnd:number}}
 */
export function readToc(data) {
  const n = Math.min(data.length, HEADER_SIZE);
  for (let i = 0; i < Math.min(n, 8); i++) {
    if (data[i] !== MAGIC[i]) {
      throw new FormatError(`not a .csgs file: magic byte ${i} is 0x${data[i].toString(16)}`, { offset: i });
    }
  }
  if (data.length < HEADER_SIZE) {
    throw new FormatError(`truncated: the header needs bytes up to ${HEADER_SIZE}`, { offset: data.length });
  }
  const h = new ByteReader(data.subarray(0, HEADER_SIZE));
  h.raw(8, 'magic');
  const major = h.u8('major_version');
  const minor = h.u8('minor_version');
  const flags = h.u16('flags');
  const tocSize = h.u32('toc_size');
  if (major !== 1) throw new FormatError(`major version ${major} is not supported`, { offset: 8 });
  if (flags & 0xff00) throw new FormatError(`reserved flag bits 0x${(flags & 0xff00).toString(16)} are set`, { offset: 10 });
  if (tocSize < 1 || tocSize > MAX_TOC_SIZE) throw new FormatError(`toc_size ${tocSize} is out of range`, { offset: 12 });
  const tocEnd = HEADER_SIZE + tocSize + 4;
  if (tocEnd > data.length) {
    throw new FormatError(`truncated: the TOC needs bytes up to ${tocEnd}`, { offset: data.length });
  }
  const stored = new DataView(data.buffer, data.byteOffset + HEADER_SIZE + tocSize, 4).getUint32(0, true);
  if (crc32(data.subarray(0, HEADER_SIZE + tocSize)) !== stored) {
    throw new FormatError('TOC CRC mismatch', { offset: HEADER_SIZE + tocSize });
  }
  const r = new ByteReader(data.subarray(HEADER_SIZE, HEADER_SIZE + tocSize), HEADER_SIZE);
  const count = r.varint('chunk_count', MAX_CHUNKS);
  if (count > Math.floor(r.remaining / 8)) {
    throw r.error(`chunk_count ${count} cannot fit in the TOC`, HEADER_SIZE);
  }
  const entries = [];
  let expected = tocEnd;
  let previousLayer = 0;
  for (let index = 0; index < count; index++) {
    const entryOffset = r.offset;
    const code = r.raw(4, 'type');
    if (!code.every(isLetter)) throw r.error(`TOC entry ${index}: type is not four ASCII letters`, entryOffset);
    const type = String.fromCharCode(...code);
    r.chunk = type;
    const layer = r.u8('layer');
    const tile = r.varint('tile', MAX_U32);
    // Any 64-bit value is a well-formed offset (§5.2 has no range, only the rule below): read
    // it whole, so a huge one is refused by that rule, as in the Python decoder, not as a
    // number above 2^53.
    const offsetBig = r.varintBig('offset');
    const length = r.varint('length', MAX_U32);
    r.chunk = null;
    const where = { chunk: type, offset: entryOffset + 4 };
    if (layer > 2) throw new FormatError(`TOC entry ${index}: layer ${layer} is not 0, 1 or 2`, where);
    if (layer < previousLayer) throw new FormatError(`TOC entry ${index}: layers out of order`, where);
    const known = type in CHUNK_LAYERS;
    if (known && CHUNK_LAYERS[type] !== null && CHUNK_LAYERS[type] !== layer) {
      throw new FormatError(`TOC entry ${index}: chunk type belongs to another layer`, where);
    }
    if (offsetBig !== BigInt(expected)) {
      throw new FormatError(`TOC entry ${index}: offset ${offsetBig} is not ${expected}`, { chunk: type, offset: entryOffset });
    }
    const offset = expected;
    entries.push({ index, type, layer, tile, offset, length, tocOffset: entryOffset, known,
      critical: !(code[0] & 0x20), end: offset + length + FRAME_OVERHEAD });
    expected += length + FRAME_OVERHEAD;
    previousLayer = layer;
  }
  r.expectEnd('the TOC');
  const fileSize = entries.length ? entries[entries.length - 1].end : tocEnd;
  if (data.length > fileSize) {
    throw new FormatError(`${data.length - fileSize} bytes follow the last chunk`, { offset: fileSize });
  }
  return { major, minor, flags, entries, tocEnd };
}

/**
 * The payload of one chunk frame after checking its length, type and CRC (§6.1).
 * @returns {Uint8Array} a view of the payload
 */
export function readFrame(data, entry) {
  if (entry.end > data.length) {
    throw new FormatError(`truncated: the chunk needs bytes up to ${entry.end}`, { chunk: entry.type, offset: data.length });
  }
  return framePayload(data, entry.offset, entry);
}

/**
 * The payload of one chunk frame fetched on its own (``frame``: its bytes, from the frame's
 * first byte), checked as readFrame checks it; errors name file offsets. A reader of byte
 * ranges (the viewer streaming levels of detail) reads frames this way.
 * @returns {Uint8Array} a view of the payload
 */
export function checkFrame(frame, entry) {
  if (frame.length < entry.length + FRAME_OVERHEAD) {
    throw new FormatError(`truncated: the chunk needs bytes up to ${entry.end}`, { chunk: entry.type, offset: entry.offset + frame.length });
  }
  return framePayload(frame, 0, entry);
}

/** The payload of the frame of ``entry`` that starts at ``start`` in ``data``. */
function framePayload(data, start, entry) {
  const shift = entry.offset - start; // file offset of data[0]
  const view = new DataView(data.buffer, data.byteOffset + start, entry.length + FRAME_OVERHEAD);
  if (view.getUint32(0, true) !== entry.length) {
    throw new FormatError('frame length differs from the TOC', { chunk: entry.type, offset: entry.offset });
  }
  for (let i = 0; i < 4; i++) {
    if (data[start + 4 + i] !== entry.type.charCodeAt(i)) {
      throw new FormatError('frame type differs from the TOC', { chunk: entry.type, offset: entry.offset + 4 });
    }
  }
  const crcAt = start + 8 + entry.length;
  if (crc32(data.subarray(start + 4, crcAt)) !== view.getUint32(8 + entry.length, true)) {
    throw new FormatError('chunk CRC mismatch', { chunk: entry.type, offset: crcAt + shift });
  }
  return data.subarray(start + 8, crcAt);
}

/**
 * Read the header, TOC and the frames of the base layer and ``layers`` (§7.2, §8).
 * @param {Uint8Array} data
 * @param {Set<string>} layers requested layer names ('color', 'semantic')
 * @returns {{toc: object, payloads: Map<number, Uint8Array>, size: number}}
 */
export function readLayers(data, layers) {
  return readPayloads(data, readToc(data), layers);
}

/**
 * readLayers after the TOC: the frames of the base layer and ``layers`` of ``toc`` (read by
 * readToc from ``data``), in TOC order.
 * @returns {{toc: object, payloads: Map<number, Uint8Array>, size: number}}
 */
export function readPayloads(data, toc, layers) {
  const wanted = new Set([0, ...[...layers].map((name) => LAYERS.indexOf(name))]);
  const needed = [];
  for (const entry of toc.entries) {
    if (!wanted.has(entry.layer)) continue;
    if (!entry.known) {
      if (entry.critical) {
        throw new FormatError(`unknown critical chunk in the ${LAYERS[entry.layer]} layer`, { chunk: entry.type, offset: entry.tocOffset });
      }
      continue;
    }
    needed.push(entry);
  }
  const payloads = new Map();
  for (const entry of needed) payloads.set(entry.index, readFrame(data, entry));
  return { toc, payloads, size: data.length };
}
