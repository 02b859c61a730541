/**
 * The decode worker's path for an anchor scene (spec/FORMAT.md §17): the splats the page
 * draws are the anchors' bake (§17.13; ../js/anchor_bake.mjs, the reference decoder's
 * ``csgs decode -o x.ply``).
 *
 * Order: the bytes up to the end of the color layer, decoded (../js/anchor_scene.mjs); a
 * preview bake from a few of the view origins with the base color only, posted at once
 * (a 'color' message with ``complete`` false), so the first frame does not wait for the
 * bake; the bake over every origin with SH bands, posted as the complete scene; then, when
 * asked, the semantic layer, whose per-anchor features and labels each baked splat takes
 * from its anchor (click selection then works as on a standard file).
 */

import { anchorArrays, decodeAnchorScene } from '../js/anchor_scene.mjs';
import { bakeAnchorScene, defaultOrigins } from '../js/anchor_bake.mjs';
import { UnsupportedError } from '../js/errors.mjs';

/** View origins of the preview bake: at most this many of the full bake's, evenly spaced. */
const PREVIEW_ORIGINS = 4;

/** ``count`` of the (V x 3) ``origins`` evenly spaced (all of them when there are fewer). */
export function evenOrigins(origins, count) {
  const views = origins.length / 3;
  if (views <= count) return origins;
  const out = new Float64Array(3 * count);
  for (let j = 0; j < count; j++) {
    const v = Math.floor((j * views) / count);
    out.set(origins.subarray(3 * v, 3 * v + 3), 3 * j);
  }
  return out;
}

/** The splat arrays of a bake the page draws (the viewer's scene layout). */
function drawable(baked, extra) {
  const { count, positions, sh_dc, sh_rest, opacity, scales, rotations, shCoefficients } = baked;
  return {
    count, positions, sh_dc, sh_rest, opacity, scales, rotations, shCoefficients,
    semantic: null, semanticNames: [], labels: null, instances: null, metadata: null, complete: true,
    ...extra,
  };
}

/** Per-splat rows of the per-anchor ``values`` (M x width) by ``anchorIndex``. */
function perSplat(values, width, anchorIndex, Type) {
  const out = new Type(anchorIndex.length * width);
  for (let g = 0; g < anchorIndex.length; g++) {
    const a = anchorIndex[g];
    for (let c = 0; c < width; c++) out[g * width + c] = values[a * width + c];
  }
  return out;
}

/**
 * Open an anchor scene for the page (module notes). ``ctx`` holds what the worker's ``open``
 * has read and its helpers: source, prefix (header and TOC bytes), colorEnd, fileEnd,
 * hasSemantic, wanted (Set of layers), tablesReady, hashes (bool), post, progress, mark,
 * concat, arrayHashes, stageOf (tells ``open`` the stage an error belongs to).
 */
export async function openAnchors(ctx) {
  const { source, prefix, colorEnd, fileEnd, hasSemantic, wanted, post, progress, mark } = ctx;
  const need = colorEnd - prefix.length;
  const body = await source.read(prefix.length, colorEnd,
    (n) => progress('color', 0.2 * n / Math.max(need, 1), `downloading the anchors: ${n.toLocaleString()} of ${need.toLocaleString()} bytes`));
  const colorBytes = ctx.concat([prefix, body]);
  mark(post, 'colorBytesRead');
  const tables = await ctx.tablesReady;
  progress('color', 0.2, 'decoding the anchors');
  mark(post, 'decodeStarted');
  const t0 = performance.now();
  const anchors = await decodeAnchorScene(colorBytes, { layers: [], tables });
  if (!anchors.mlps) {
    throw new UnsupportedError('this anchor scene stores no Scaffold-GS MLPs (AMLP), so it has no splats to draw');
  }
  mark(post, 'anchorsDecoded');
  const origins = anchors.viewOrigins && anchors.viewOrigins.length ? anchors.viewOrigins
    : defaultOrigins(anchors.positions, anchors.count);
  const preview = bakeAnchorScene(anchors, { origins: evenOrigins(origins, PREVIEW_ORIGINS), shDegree: 0 });
  post({ kind: 'color', scene: drawable(preview, { fileEnd, colorEnd }), complete: false,
    bytesRead: colorBytes.length, decodeMs: performance.now() - t0 });
  progress('color', 0.3, 'baking the anchors into splats');
  const baked = bakeAnchorScene(anchors, {
    origins, onProgress: (f) => progress('color', 0.3 + 0.7 * f, 'baking the anchors into splats'),
  });
  const decodeMs = performance.now() - t0;
  mark(post, 'colorDecoded');
  post({ kind: 'color', scene: drawable(baked, { fileEnd, colorEnd }), complete: true,
    bytesRead: colorBytes.length, decodeMs });
  if (!wanted.has('semantic') || !hasSemantic) {
    if (ctx.hashes) post({ kind: 'hashes', arrays: await ctx.arrayHashes(anchors, anchorArrays) });
    post({ kind: 'done' });
    return;
  }
  ctx.stageOf('semantic');
  const more = fileEnd - colorEnd;
  const rest = await source.read(colorEnd, fileEnd,
    (n) => progress('semantic', 0.5 * n / Math.max(more, 1), `downloading the semantic layer: ${n.toLocaleString()} of ${more.toLocaleString()} bytes`));
  const whole = ctx.concat([colorBytes, rest]);
  progress('semantic', 0.5, 'decoding the semantic layer');
  const t1 = performance.now();
  const full = await decodeAnchorScene(whole, { layers: ['semantic'], tables });
  const channels = full.semantic ? full.semanticNames.length : 0;
  post({
    kind: 'semantic',
    semantic: full.semantic ? perSplat(full.semantic, channels, baked.anchorIndex, Float32Array) : null,
    channels, names: full.semanticNames,
    labels: full.labels ? perSplat(full.labels, 1, baked.anchorIndex, Int32Array) : null,
    bytesRead: whole.length, decodeMs: performance.now() - t1,
  });
  if (ctx.hashes) post({ kind: 'hashes', arrays: await ctx.arrayHashes(full, anchorArrays) });
  post({ kind: 'done' });
}
