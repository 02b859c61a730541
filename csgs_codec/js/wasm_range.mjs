/**
 * The range decoder loop of spec/FORMAT.md §16.2.4 as a small WebAssembly function, for
 * speed: WebAssembly has the 64-bit unsigned integers the spec's arithmetic uses, so the loop
 * is the spec's steps one for one. The module is assembled here from the instruction list
 * below (no build step, no binary blob): ``assemble`` writes the standard binary format.
 *
 * Memory layout of an instance: bytes 0..31 hold the decoder state (d = point - lower as u64
 * at 0, range u64 at 8, pos u32 at 16, word count u32 at 20, address of the words u32 at
 * 24); from byte 64 on, an arena holds the words of the current decoder, the coder views and
 * lookup indices of the tables in use, and the output symbols.
 */

import { I32, I64, moduleBytes, op } from './wasm_assembler.mjs';

// Parameters and locals of decode(view, index, out, count, shift) -> symbols decoded.
const VIEW = 0; const INDEX = 1; const OUT = 2; const COUNT = 3; const SHIFT = 4;
const I = 5; const S = 6; const Q32 = 7; const LOW = 8; const WIDTH = 9; const POS = 10;
const NWORDS = 11; const WORDS = 12; const P = 13;
const D = 14; const RANGE = 15; const SCALE = 16; const Q = 17;

/** The body of decode: §16.2.4 steps 1-6 for ``count`` symbols of one table. */
function decodeBody() {
  const addr4 = (base, index) => [op.get(base), op.get(index), op.i32Const(2), op.i32Shl, op.i32Add];
  return [
    // Load the state.
    op.i32Const(0), op.i64Load(0), op.set(D),
    op.i32Const(0), op.i64Load(8), op.set(RANGE),
    op.i32Const(0), op.i32Load(16), op.set(POS),
    op.i32Const(0), op.i32Load(20), op.set(NWORDS),
    op.i32Const(0), op.i32Load(24), op.set(WORDS),
    op.i32Const(0), op.set(I),
    op.block, op.loop,
    op.get(I), op.get(COUNT), op.i32GeU, op.brIf(1),
    // 1. scale = range >> 24;  2. quantile = d / scale;  3. fail if quantile >= 2^24.
    op.get(RANGE), op.i64Const(24), op.i64ShrU, op.set(SCALE),
    op.get(D), op.get(SCALE), op.i64DivU, op.set(Q),
    op.get(Q), op.i64Const(16777216), op.i64GeU, op.brIf(1),
    op.get(Q), op.i32WrapI64, op.set(Q32),
    // 4. the symbol: start at index[quantile >> shift], step while L[s + 1] <= quantile.
    op.get(INDEX), op.get(Q32), op.get(SHIFT), op.i32ShrU, op.i32Const(2), op.i32Shl, op.i32Add,
    op.i32Load(0), op.set(S),
    op.block, op.loop,
    ...addr4(VIEW, S), op.i32Load(4), op.get(Q32), op.i32GtU, op.brIf(1),
    op.get(S), op.i32Const(1), op.i32Add, op.set(S), op.br(0),
    op.end, op.end,
    ...addr4(OUT, I), op.get(S), op.i32Store(0),
    ...addr4(VIEW, S), op.set(P),
    op.get(P), op.i32Load(0), op.set(LOW),
    op.get(P), op.i32Load(4), op.get(LOW), op.i32Sub, op.set(WIDTH),
    // 5. d -= scale * L[s]  (lower += scale * L[s]);  range = scale * (L[s+1] - L[s]).
    op.get(D), op.get(SCALE), op.get(LOW), op.i64ExtendI32U, op.i64Mul, op.i64Sub, op.set(D),
    op.get(SCALE), op.get(WIDTH), op.i64ExtendI32U, op.i64Mul, op.set(RANGE),
    // 6. renormalise when range < 2^32: shift in the next word (0 past the end).
    op.get(RANGE), op.i64Const(4294967296n), op.i64LtU, op.if,
    op.get(RANGE), op.i64Const(32), op.i64Shl, op.set(RANGE),
    op.get(D), op.i64Const(32), op.i64Shl,
    op.get(POS), op.get(NWORDS), op.i32LtU, op.ifI64,
    ...addr4(WORDS, POS), op.i64Load32U(0),
    op.else, op.i64Const(0), op.end,
    op.i64Or, op.set(D),
    op.get(POS), op.i32Const(1), op.i32Add, op.set(POS),
    op.end,
    op.get(I), op.i32Const(1), op.i32Add, op.set(I), op.br(0),
    op.end, op.end,
    // Store the state; return how many symbols were decoded (count unless step 3 failed).
    op.i32Const(0), op.get(D), op.i64Store(0),
    op.i32Const(0), op.get(RANGE), op.i64Store(8),
    op.i32Const(0), op.get(POS), op.i32Store(16),
    op.get(I),
  ].flat();
}

/** The module's bytes: one function ``decode`` and one exported memory. */
export function assemble() {
  return moduleBytes({
    exportName: 'decode', params: [I32, I32, I32, I32, I32], results: [I32],
    locals: [[9, I32], [4, I64]], body: decodeBody(),
  });
}

let instance = null;

/** This thread's instance, or null where WebAssembly is not available. */
export function wasmInstance() {
  if (instance === null && typeof WebAssembly === 'object') {
    instance = new WebAssembly.Instance(new WebAssembly.Module(assemble()), {});
  }
  return instance;
}
