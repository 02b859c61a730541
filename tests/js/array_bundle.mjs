/**
 * Test helper: the typed-array bundles of tests/js/array_bundle.py (u32 header length, JSON
 * header, raw little-endian bytes).
 */

const TYPES = { float32: Float32Array, float64: Float64Array, int32: Int32Array, uint8: Uint8Array };

/** {arrays: {name: typed array}, shapes: {name: shape}, meta} of a bundle (a Uint8Array). */
export function unpack(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const length = view.getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(bytes.subarray(4, 4 + length)));
  const body = bytes.slice(4 + length); // a copy, so every array is aligned
  const arrays = {}, shapes = {};
  for (const [name, spec] of Object.entries(header.arrays)) {
    const Type = TYPES[spec.dtype];
    const count = spec.shape.reduce((a, b) => a * b, 1);
    arrays[name] = new Type(body.buffer, spec.offset, count);
    shapes[name] = spec.shape;
  }
  return { arrays, shapes, meta: header.meta };
}

/** A bundle (Uint8Array) of ``arrays`` {name: [typed array, shape]} and ``meta``. */
export function pack(arrays, meta = {}) {
  const header = { meta, arrays: {} };
  const parts = [];
  let offset = 0;
  for (const [name, [values, shape]] of Object.entries(arrays)) {
    const dtype = Object.keys(TYPES).find((key) => values instanceof TYPES[key]);
    header.arrays[name] = { dtype, shape, offset };
    const raw = new Uint8Array(values.buffer, values.byteOffset, values.byteLength);
    parts.push(raw);
    offset += raw.length;
  }
  const text = new TextEncoder().encode(JSON.stringify(header));
  const out = new Uint8Array(4 + text.length + offset);
  new DataView(out.buffer).setUint32(0, text.length, true);
  out.set(text, 4);
  let at = 4 + text.length;
  for (const raw of parts) { out.set(raw, at); at += raw.length; }
  return out;
}
