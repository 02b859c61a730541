/**
 * A small WebAssembly assembler: the binary format's encodings (LEB128, vectors, sections)
 * and the instructions the receiver's loops use, so that those loops are written here as
 * instruction lists and assembled at load (no build step, no binary blob). Opcodes are those
 * of the WebAssembly core specification 2.0 (SIMD instructions: 0xfd prefix).
 */

export const I32 = 0x7f;
export const I64 = 0x7e;
export const F64 = 0x7c;
export const V128 = 0x7b;

/** Unsigned LEB128. */
export function uleb(value) {
  const out = [];
  let v = value;
  do {
    let byte = v & 0x7f;
    v = Math.floor(v / 128);
    if (v) byte |= 0x80;
    out.push(byte);
  } while (v);
  return out;
}

/** Signed LEB128 of a BigInt. */
export function sleb(value) {
  const out = [];
  let v = BigInt(value);
  while (true) {
    const byte = Number(v & 0x7fn);
    v >>= 7n;
    const done = (v === 0n && !(byte & 0x40)) || (v === -1n && (byte & 0x40));
    out.push(done ? byte : byte | 0x80);
    if (done) return out;
  }
}

const vec = (items) => [...uleb(items.length), ...items.flat()];
const section = (id, bytes) => [id, ...uleb(bytes.length), ...bytes];
const name = (text) => vec([...text].map((c) => [c.charCodeAt(0)]));
const simd = (code) => [0xfd, ...uleb(code)];

/** Instructions (byte lists; functions of their immediates). */
export const op = {
  block: [0x02, 0x40], loop: [0x03, 0x40], if: [0x04, 0x40], ifI64: [0x04, I64], else: [0x05],
  end: [0x0b], br: (d) => [0x0c, ...uleb(d)], brIf: (d) => [0x0d, ...uleb(d)],
  get: (i) => [0x20, ...uleb(i)], set: (i) => [0x21, ...uleb(i)], tee: (i) => [0x22, ...uleb(i)],
  i32Load: (offset) => [0x28, 2, ...uleb(offset)], i64Load: (offset) => [0x29, 3, ...uleb(offset)],
  f64Load: (offset) => [0x2b, 3, ...uleb(offset)],
  i64Load32U: (offset) => [0x35, 2, ...uleb(offset)],
  i32Store: (offset) => [0x36, 2, ...uleb(offset)], i64Store: (offset) => [0x37, 3, ...uleb(offset)],
  i32Const: (v) => [0x41, ...sleb(v)], i64Const: (v) => [0x42, ...sleb(v)],
  i32LtU: [0x49], i32GtU: [0x4b], i32GeU: [0x4f], i64LtU: [0x54], i64GeU: [0x5a],
  i32Add: [0x6a], i32Sub: [0x6b], i32Mul: [0x6c], i32Shl: [0x74], i32ShrU: [0x76],
  i64Sub: [0x7d], i64Mul: [0x7e], i64DivU: [0x80], i64Or: [0x84], i64Shl: [0x86], i64ShrU: [0x88],
  i32WrapI64: [0xa7], i64ExtendI32U: [0xad],
  v128Load: (offset) => [...simd(0x00), 4, ...uleb(offset)],
  v128Store: (offset) => [...simd(0x0b), 4, ...uleb(offset)],
  f64x2Splat: simd(0x14), f64x2Floor: simd(0x75), f64x2Add: simd(0xf0), f64x2Mul: simd(0xf2),
  f64x2Min: simd(0xf4), f64x2Max: simd(0xf5),
};

/**
 * The bytes of a module with one function ``exportName`` of type (params) -> (results),
 * ``locals`` ([[count, type], ...]) and instruction list ``body``, and one exported memory
 * ``memory`` of ``pages`` initial 64 KiB pages.
 */
export function moduleBytes({ exportName, params, results, locals, body, pages = 2 }) {
  const type = [0x60, ...vec(params.map((t) => [t])), ...vec(results.map((t) => [t]))];
  const code = [...vec(locals.map(([count, t]) => [...uleb(count), t])), ...body.flat(), ...op.end];
  return new Uint8Array([
    0x00, 0x61, 0x73, 0x6d, 0x01, 0x00, 0x00, 0x00,
    ...section(1, vec([type])),
    ...section(3, vec([[0]])),
    ...section(5, vec([[0x00, ...uleb(pages)]])),
    ...section(7, vec([[...name(exportName), 0x00, 0], [...name('memory'), 0x02, 0]])),
    ...section(10, vec([[...uleb(code.length), ...code]])),
  ]);
}
