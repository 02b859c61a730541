/**
 * Bounds-checked reading of the format's primitives (spec/FORMAT.md §2): fixed-size
 * little-endian numbers, LEB128 varints in shortest form, zigzag svarints, byte strings.
 * Every failure is a FormatError naming the chunk and the absolute byte offset.
 */

import { FormatError } from './errors.mjs';

const TWO_64 = 1n << 64n;

export class ByteReader {
  /**
   * @param {Uint8Array} bytes the buffer (a view; not copied)
   * @param {number} baseOffset absolute file offset of bytes[0]
   * @param {string|null} chunk chunk type named in errors
   */
  constructor(bytes, baseOffset = 0, chunk = null) {
    this.bytes = bytes;
    this.pos = 0;
    this.baseOffset = baseOffset;
    this.chunk = chunk;
    this.view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  }

  /** Absolute offset of the next byte. */
  get offset() { return this.baseOffset + this.pos; }

  /** Bytes not yet read. */
  get remaining() { return this.bytes.length - this.pos; }

  /** A FormatError at absolute offset ``at`` (default: the next byte). */
  error(message, at = null) {
    return new FormatError(message, { chunk: this.chunk, offset: at === null ? this.offset : at });
  }

  /** Consume ``n`` bytes; returns the position where they start. */
  take(n, field) {
    if (n < 0 || n > this.remaining) {
      throw this.error(`truncated: field '${field}' needs ${n} bytes, ${this.remaining} remain`,
        this.baseOffset + this.bytes.length);
    }
    const at = this.pos;
    this.pos += n;
    return at;
  }

  /** The next ``n`` bytes as a subarray view. */
  raw(n, field) {
    const at = this.take(n, field);
    return this.bytes.subarray(at, at + n);
  }

  u8(field) { return this.bytes[this.take(1, field)]; }
  u16(field) { return this.view.getUint16(this.take(2, field), true); }
  u32(field) { return this.view.getUint32(this.take(4, field), true); }
  f32(field) { return this.view.getFloat32(this.take(4, field), true); }
  f64(field) { return this.view.getFloat64(this.take(8, field), true); }
  i64(field) { return this.view.getBigInt64(this.take(8, field), true); }

  /**
   * An unsigned varint as a BigInt, checked against ``maximum`` (BigInt).
   * @returns {bigint}
   */
  varintBig(field, maximum = TWO_64 - 1n) {
    const start = this.offset;
    let value = 0n;
    for (let i = 0; i < 10; i++) {
      if (this.remaining === 0) throw this.error(`truncated: varint field '${field}' runs past the end`);
      const byte = this.bytes[this.pos++];
      value |= BigInt(byte & 0x7f) << BigInt(7 * i);
      if (!(byte & 0x80)) {
        if (i > 0 && byte === 0) throw this.error(`varint field '${field}' is not in shortest form`, start);
        if (value >= TWO_64) throw this.error(`varint field '${field}' exceeds 2**64-1`, start);
        if (value > maximum) throw this.error(`field '${field}' = ${value} exceeds the limit ${maximum}`, start);
        return value;
      }
    }
    throw this.error(`varint field '${field}' is longer than 10 bytes`, start);
  }

  /**
   * An unsigned varint as a Number (exact below 2^53), checked against ``maximum``.
   * @returns {number}
   */
  varint(field, maximum = Number.MAX_SAFE_INTEGER) {
    const pos = this.pos;
    if (pos < this.bytes.length) {
      const b0 = this.bytes[pos];
      if (b0 < 0x80 && b0 <= maximum) { this.pos = pos + 1; return b0; }
    }
    const start = this.offset;
    let value = 0;
    let scale = 1;
    for (let i = 0; i < 10; i++) {
      if (this.remaining === 0) throw this.error(`truncated: varint field '${field}' runs past the end`);
      const byte = this.bytes[this.pos++];
      value += (byte & 0x7f) * scale;
      scale *= 128;
      if (!(byte & 0x80)) {
        if (i > 0 && byte === 0) throw this.error(`varint field '${field}' is not in shortest form`, start);
        if (i === 9 && byte > 1) throw this.error(`varint field '${field}' exceeds 2**64-1`, start);
        if (value > maximum) throw this.error(`field '${field}' = ${value} exceeds the limit ${maximum}`, start);
        return value;
      }
    }
    throw this.error(`varint field '${field}' is longer than 10 bytes`, start);
  }

  /** A zigzag svarint as a BigInt. */
  svarintBig(field) {
    const z = this.varintBig(field);
    return z & 1n ? -((z + 1n) >> 1n) : z >> 1n;
  }

  /** A length-prefixed byte string (length checked before use). Returns a subarray. */
  byteString(field, maximum = null) {
    const limit = maximum === null ? this.remaining : Math.min(maximum, this.remaining);
    const start = this.offset;
    const length = this.varint(field);
    if (length > limit) throw this.error(`field '${field}' declares ${length} bytes, only ${limit} allowed`, start);
    return this.raw(length, field);
  }

  /** Throw unless every byte has been read. */
  expectEnd(what) {
    if (this.remaining) throw this.error(`${this.remaining} unexpected bytes after the last field of ${what}`);
  }
}

/** Convert a BigInt known to be below 2^53 in magnitude to a Number. */
export function small(big) { return Number(big); }
