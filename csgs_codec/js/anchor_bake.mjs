/**
 * The bake of spec/FORMAT.md §17.13: the standard 3DGS scene an anchor scene's Scaffold-GS
 * heads generate, seen from a set of view origins, as the reference decoder's
 * ``csgs decode anchors.csgs -o x.ply`` writes it (csgs_codec/bake/anchor_bake.py).
 *
 * For every anchor-offset slot, over the origins: kept when its opacity head is > 0 from at
 * least ``keepFraction`` of them (and its offset is not masked); opacity the mean of the
 * positive values; log-scale their opacity-weighted mean; rotation the principal axis of the
 * weighted q q^T; SH colour of ``shDegree`` by weighted least squares with a ridge on the
 * non-DC coefficients. All arithmetic is float64 (the reference runs its heads in float32),
 * so the two bakes agree to float tolerance, not bit for bit: a bake feeds no range coder.
 *
 * Input: a decoded anchor scene as plain typed arrays (see ``bakeAnchorScene``). Output: a
 * scene object of the JavaScript receiver's layout (``count``, ``positions``, ``sh_dc``,
 * ``sh_rest`` N x R x 3, ``opacity`` logits, ``scales`` logs, ``rotations`` w x y z, and the
 * anchors' ``semantic`` / ``labels`` repeated per Gaussian), which the viewer draws as it
 * draws a standard file. No imports: runs in Node and in a browser worker.
 */

/** The reference decoder's bake settings (csgs_codec.bake.anchor_bake.BakeSettings). */
export const BAKE_DEFAULTS = Object.freeze({
  shDegree: 3, keepFraction: 0.5, ridge: 1e-3, directions: 32, distances: [0.65, 1.0, 1.5],
});

const MAX_OPACITY = 1 - 2 ** -24;
const MIN_COLOR_WEIGHT = 1e-4;
const SH_C0 = 0.28209479177387814;
const SH_C1 = 0.4886025119029199;
const SH_C2 = [1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
  0.5462742152960396];
const SH_C3 = [-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
  -0.4570457994644658, 1.445305721320277, -0.5900435899266435];
const BASIS_COUNTS = [1, 4, 9, 16];
/** The default sphere's framing (render/view_distribution.py): a 40-degree frame of 800 x
 * 600 that the robust extent fills to 70%. */
const FRAMING_PER_EXTENT = 0.5 / 0.7 / Math.tan((20 * Math.PI) / 180) + 0.5;

/** Real SH basis (INRIA order) of degree ``degree`` at unit direction (x, y, z) into ``out``. */
function shBasis(x, y, z, degree, out) {
  out[0] = SH_C0;
  if (degree < 1) return;
  out[1] = -SH_C1 * y; out[2] = SH_C1 * z; out[3] = -SH_C1 * x;
  if (degree < 2) return;
  const xx = x * x, yy = y * y, zz = z * z;
  out[4] = SH_C2[0] * x * y; out[5] = SH_C2[1] * y * z; out[6] = SH_C2[2] * (2 * zz - xx - yy);
  out[7] = SH_C2[3] * x * z; out[8] = SH_C2[4] * (xx - yy);
  if (degree < 3) return;
  out[9] = SH_C3[0] * y * (3 * xx - yy); out[10] = SH_C3[1] * x * y * z;
  out[11] = SH_C3[2] * y * (4 * zz - xx - yy); out[12] = SH_C3[3] * z * (2 * zz - 3 * xx - 3 * yy);
  out[13] = SH_C3[4] * x * (4 * zz - xx - yy); out[14] = SH_C3[5] * z * (xx - yy);
  out[15] = SH_C3[6] * x * (xx - 3 * yy);
}

/** The ``p``-th percentile (0..100) of ``sorted`` values, linearly interpolated (numpy's
 * default). */
function percentile(sorted, p) {
  const h = ((sorted.length - 1) * p) / 100;
  const lo = Math.floor(h);
  const hi = Math.min(lo + 1, sorted.length - 1);
  return sorted[lo] + (h - lo) * (sorted[hi] - sorted[lo]);
}

/**
 * View origins for a scene without stored ones (§17.13): Fibonacci spheres of ``directions``
 * points around the centre of the anchors' 2nd-98th percentile box, at ``distances`` times
 * the framing distance of its largest side, each shell turned by 2 pi shell / (shells x
 * directions) about z.
 * @returns {Float64Array} (V x 3) origins, world units.
 */
export function defaultOrigins(positions, count, settings = BAKE_DEFAULTS) {
  const low = [0, 0, 0], high = [0, 0, 0];
  for (let axis = 0; axis < 3; axis++) {
    const values = new Float64Array(count);
    for (let i = 0; i < count; i++) values[i] = positions[3 * i + axis];
    values.sort();
    low[axis] = count ? percentile(values, 2) : 0;
    high[axis] = count ? percentile(values, 98) : 0;
  }
  let extent = Math.max(high[0] - low[0], high[1] - low[1], high[2] - low[2]);
  if (!(extent > 0)) extent = 1;
  const base = extent * FRAMING_PER_EXTENT;
  const n = settings.directions, shells = settings.distances;
  const out = new Float64Array(3 * n * shells.length);
  let at = 0;
  shells.forEach((factor, shell) => {
    const turn = (2 * Math.PI * shell) / (shells.length * n);
    const c = Math.cos(turn), s = Math.sin(turn);
    for (let j = 0; j < n; j++) {
      const i = j + 0.5;
      const z = 1 - (2 * i) / n;
      const radius = Math.sqrt(Math.max(0, 1 - z * z));
      const phi = i * Math.PI * (3 - Math.sqrt(5));
      const x = radius * Math.cos(phi), y = radius * Math.sin(phi);
      out[at++] = (low[0] + high[0]) / 2 + base * factor * (c * x - s * y);
      out[at++] = (low[1] + high[1]) / 2 + base * factor * (s * x + c * y);
      out[at++] = (low[2] + high[2]) / 2 + base * factor * z;
    }
  });
  return out;
}

/** One head prepared for the bake: the part of its first layer that does not depend on the
 * view (features, appearance) is computed once per anchor by ``headBase``. */
function prepareHead(head, featDim, appearance) {
  const hidden = head.b1.length, inDim = head.w1.length / hidden, outDim = head.b2.length;
  const extra = appearance ? appearance.length : 0;
  const usesDistance = inDim - featDim - 3 - extra === 1;
  if (inDim - featDim - 3 - extra !== (usesDistance ? 1 : 0)) {
    throw new RangeError(`a head's input width ${inDim} does not fit ${featDim} features`);
  }
  const fixed = new Float64Array(hidden); // b1 + W1[:, appearance] . mean appearance
  for (let h = 0; h < hidden; h++) {
    let sum = head.b1[h];
    const row = h * inDim + featDim + 3 + (usesDistance ? 1 : 0);
    for (let a = 0; a < extra; a++) sum += head.w1[row + a] * appearance[a];
    fixed[h] = sum;
  }
  return { w1: head.w1, w2: head.w2, b2: head.b2, hidden, inDim, outDim, usesDistance, fixed,
    viewColumn: featDim };
}

function headBase(head, features, anchor, featDim, out) {
  const f0 = anchor * featDim;
  for (let h = 0; h < head.hidden; h++) {
    let sum = head.fixed[h];
    const row = h * head.inDim;
    for (let j = 0; j < featDim; j++) sum += head.w1[row + j] * features[f0 + j];
    out[h] = sum;
  }
}

/** The hidden layer of ``head`` for one view: its base plus the view terms, ReLU. */
function headHidden(head, base, dx, dy, dz, dist, out) {
  const { w1, hidden, inDim, viewColumn } = head;
  for (let h = 0; h < hidden; h++) {
    const at = h * inDim + viewColumn;
    let sum = base[h] + w1[at] * dx + w1[at + 1] * dy + w1[at + 2] * dz;
    if (head.usesDistance) sum += w1[at + 3] * dist;
    out[h] = sum > 0 ? sum : 0;
  }
}

/** Outputs ``first`` .. ``first + count - 1`` of ``head``'s second layer (no activation)
 * from its ``hidden`` values, into ``out`` at the same indices. */
function headRows(head, hidden, first, count, out) {
  const { w2, b2 } = head;
  const width = head.hidden, whole = width - (width % 4);
  for (let o = first; o < first + count; o++) {
    // Four running sums: one chain of dependent additions is latency bound.
    let s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    const row = o * width;
    let h = 0;
    for (; h < whole; h += 4) {
      s0 += w2[row + h] * hidden[h];
      s1 += w2[row + h + 1] * hidden[h + 1];
      s2 += w2[row + h + 2] * hidden[h + 2];
      s3 += w2[row + h + 3] * hidden[h + 3];
    }
    for (; h < width; h++) s0 += w2[row + h] * hidden[h];
    out[o] = b2[o] + ((s0 + s1) + (s2 + s3));
  }
}

/** Principal eigenvector (largest eigenvalue) of the symmetric 4 x 4 matrix ``m`` (row
 * major, destroyed) by cyclic Jacobi rotations, into ``out``. */
function principalAxis4(m, out) {
  const v = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
  for (let sweep = 0; sweep < 32; sweep++) {
    let off = 0;
    for (let p = 0; p < 4; p++) for (let q = p + 1; q < 4; q++) off += m[4 * p + q] ** 2;
    if (off < 1e-30 * (m[0] ** 2 + m[5] ** 2 + m[10] ** 2 + m[15] ** 2) || off === 0) break;
    for (let p = 0; p < 3; p++) {
      for (let q = p + 1; q < 4; q++) {
        const apq = m[4 * p + q];
        if (apq === 0) continue;
        const theta = (m[4 * q + q] - m[4 * p + p]) / (2 * apq);
        const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
        const c = 1 / Math.sqrt(t * t + 1), s = t * c;
        for (let k = 0; k < 4; k++) { // columns p, q of m
          const mkp = m[4 * k + p], mkq = m[4 * k + q];
          m[4 * k + p] = c * mkp - s * mkq;
          m[4 * k + q] = s * mkp + c * mkq;
        }
        for (let k = 0; k < 4; k++) { // rows p, q
          const mpk = m[4 * p + k], mqk = m[4 * q + k];
          m[4 * p + k] = c * mpk - s * mqk;
          m[4 * q + k] = s * mpk + c * mqk;
        }
        for (let k = 0; k < 4; k++) {
          const vkp = v[4 * k + p], vkq = v[4 * k + q];
          v[4 * k + p] = c * vkp - s * vkq;
          v[4 * k + q] = s * vkp + c * vkq;
        }
      }
    }
  }
  let best = 0;
  for (let k = 1; k < 4; k++) if (m[5 * k] > m[5 * best]) best = k;
  let norm = 0;
  for (let k = 0; k < 4; k++) norm += v[4 * k + best] ** 2;
  norm = Math.sqrt(norm) || 1;
  const sign = v[best] < 0 ? -1 : 1;
  for (let k = 0; k < 4; k++) out[k] = (sign * v[4 * k + best]) / norm;
}

/** Solve the symmetric positive definite ``n`` x ``n`` system ``a`` x = ``b`` (3 right-hand
 * sides, ``b`` n x 3) by Cholesky, in place: ``b`` becomes x. */
function solveSpd(a, b, n) {
  for (let j = 0; j < n; j++) {
    let d = a[j * n + j];
    for (let k = 0; k < j; k++) d -= a[j * n + k] ** 2;
    d = Math.sqrt(Math.max(d, 1e-300));
    a[j * n + j] = d;
    for (let i = j + 1; i < n; i++) {
      let s = a[i * n + j];
      for (let k = 0; k < j; k++) s -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = s / d;
    }
  }
  for (let c = 0; c < 3; c++) {
    for (let i = 0; i < n; i++) { // L y = b
      let s = b[3 * i + c];
      for (let k = 0; k < i; k++) s -= a[i * n + k] * b[3 * k + c];
      b[3 * i + c] = s / a[i * n + i];
    }
    for (let i = n - 1; i >= 0; i--) { // L^T x = y
      let s = b[3 * i + c];
      for (let k = i + 1; k < n; k++) s -= a[k * n + i] * b[3 * k + c];
      b[3 * i + c] = s / a[i * n + i];
    }
  }
}

/**
 * Bake a decoded anchor scene into standard Gaussians (module notes).
 *
 * @param {object} anchors ``count`` M, ``featDim`` F, ``nOffsets`` K, ``positions`` (M x 3),
 *   ``features`` (M x F), ``offsets`` (M x K x 3), ``scaling`` (M x 6), ``offsetMask``
 *   (M x K, nonzero = used), ``mlps`` {opacity, cov, color: {w1 (H x D), b1, w2 (O x H), b2},
 *   appearance: (C x A) Float32Array or null, appearanceCount C}, ``viewOrigins`` (V x 3) or
 *   null, and optionally ``semantic`` (M x S), ``semanticNames``, ``labels`` (M).
 * @param {object} options ``origins`` (V x 3, overrides the stored ones), and any of
 *   BAKE_DEFAULTS; ``onProgress(fraction)`` after each block of anchors.
 * @returns {object} the baked scene (module notes), with ``anchorIndex`` (N, Int32Array).
 */
export function bakeAnchorScene(anchors, options = {}) {
  const settings = { ...BAKE_DEFAULTS, ...options };
  const degree = settings.shDegree;
  if (!(degree >= 0 && degree <= 3 && Number.isInteger(degree))) {
    throw new RangeError(`SH degree must be 0..3, got ${degree}`);
  }
  const m = anchors.count, f = anchors.featDim, k = anchors.nOffsets;
  const origins = options.origins
    || (anchors.viewOrigins && anchors.viewOrigins.length ? anchors.viewOrigins
      : defaultOrigins(anchors.positions, m, settings));
  const views = origins.length / 3;
  if (views < 1) throw new RangeError('the bake needs at least one view origin');
  const mlps = anchors.mlps;
  let appearance = null;
  if (mlps.appearance && mlps.appearance.length) {
    const count = mlps.appearanceCount, width = mlps.appearance.length / count;
    appearance = new Float64Array(width);
    for (let c = 0; c < count; c++) for (let a = 0; a < width; a++) appearance[a] += mlps.appearance[c * width + a];
    for (let a = 0; a < width; a++) appearance[a] /= count;
  }
  const heads = [prepareHead(mlps.opacity, f, null), prepareHead(mlps.cov, f, null),
    prepareHead(mlps.color, f, appearance)];
  const [opacityHead, covHead, colorHead] = heads;
  const basisCount = BASIS_COUNTS[degree];
  const bases = heads.map((h) => new Float64Array(h.hidden));
  const hiddenValues = heads.map((h) => new Float64Array(h.hidden));
  const opacityOut = new Float64Array(k), covOut = new Float64Array(7 * k), colorOut = new Float64Array(3 * k);
  const weights = new Float64Array(views * k), colors = new Float64Array(views * k * 3);
  const onCount = new Float64Array(k), weightSum = new Float64Array(k);
  const logScaleSum = new Float64Array(3 * k), moment = new Float64Array(16 * k);
  const centers = new Float64Array(3 * k), basis = new Float64Array(16);
  const normal = new Float64Array(basisCount * basisCount), target = new Float64Array(3 * basisCount);
  const axis = new Float64Array(4), scratch4 = new Float64Array(16);
  const out = { anchorIndex: [], positions: [], sh: [], opacity: [], scales: [], rotations: [] };
  const { positions, features, offsets, scaling, offsetMask } = anchors;
  const block = 256;
  for (let i = 0; i < m; i++) {
    heads.forEach((head, h) => headBase(head, features, i, f, bases[h]));
    const px = positions[3 * i], py = positions[3 * i + 1], pz = positions[3 * i + 2];
    for (let s = 0; s < k; s++) {
      for (let a = 0; a < 3; a++) {
        centers[3 * s + a] = positions[3 * i + a]
          + offsets[(i * k + s) * 3 + a] * Math.exp(scaling[6 * i + a]);
      }
    }
    onCount.fill(0); weightSum.fill(0); logScaleSum.fill(0); moment.fill(0);
    for (let v = 0; v < views; v++) {
      const dx0 = px - origins[3 * v], dy0 = py - origins[3 * v + 1], dz0 = pz - origins[3 * v + 2];
      const dist = Math.sqrt(dx0 * dx0 + dy0 * dy0 + dz0 * dz0);
      const inv = 1 / Math.max(dist, 1.1754943508222875e-38);
      const dx = dx0 * inv, dy = dy0 * inv, dz = dz0 * inv;
      heads.forEach((head, h) => headHidden(head, bases[h], dx, dy, dz, dist, hiddenValues[h]));
      headRows(opacityHead, hiddenValues[0], 0, k, opacityOut);
      for (let s = 0; s < k; s++) {
        const used = offsetMask[i * k + s] ? 1 : 0;
        const weight = Math.max(Math.tanh(opacityOut[s]), 0) * used;
        weights[v * k + s] = weight;
        if (!used) continue;
        // Only slots on from this origin shape the scale and rotation; every used slot's
        // colour enters its fit (with a floor weight where it is off).
        headRows(colorHead, hiddenValues[2], 3 * s, 3, colorOut);
        for (let c = 0; c < 3; c++) colors[(v * k + s) * 3 + c] = 1 / (1 + Math.exp(-colorOut[3 * s + c]));
        if (weight > 0) onCount[s] += 1;
        weightSum[s] += weight;
        if (weight === 0) continue;
        headRows(covHead, hiddenValues[1], 7 * s, 7, covOut);
        for (let a = 0; a < 3; a++) {
          const logit = covOut[7 * s + a]; // log sigmoid, stable for either sign
          const logSigmoid = logit >= 0 ? -Math.log1p(Math.exp(-logit)) : logit - Math.log1p(Math.exp(logit));
          logScaleSum[3 * s + a] += weight * (scaling[6 * i + 3 + a] + logSigmoid);
        }
        let qn = 0;
        for (let a = 0; a < 4; a++) qn += covOut[7 * s + 3 + a] ** 2;
        qn = Math.max(Math.sqrt(qn), 1e-12);
        for (let a = 0; a < 4; a++) {
          const qa = covOut[7 * s + 3 + a] / qn;
          for (let b = 0; b < 4; b++) moment[16 * s + 4 * a + b] += weight * qa * (covOut[7 * s + 3 + b] / qn);
        }
      }
    }
    for (let s = 0; s < k; s++) {
      if (!(offsetMask[i * k + s] && weightSum[s] > 0 && onCount[s] >= settings.keepFraction * views)) continue;
      let peak = 0;
      for (let v = 0; v < views; v++) peak = Math.max(peak, weights[v * k + s]);
      normal.fill(0); target.fill(0);
      for (let v = 0; v < views; v++) {
        const gx = centers[3 * s] - origins[3 * v], gy = centers[3 * s + 1] - origins[3 * v + 1];
        const gz = centers[3 * s + 2] - origins[3 * v + 2];
        const gn = Math.max(Math.sqrt(gx * gx + gy * gy + gz * gz), 1e-12);
        shBasis(gx / gn, gy / gn, gz / gn, degree, basis);
        const w = Math.max(weights[v * k + s], MIN_COLOR_WEIGHT * peak);
        for (let a = 0; a < basisCount; a++) {
          const wa = w * basis[a];
          for (let b = 0; b <= a; b++) normal[a * basisCount + b] += wa * basis[b];
          for (let c = 0; c < 3; c++) target[3 * a + c] += wa * (colors[(v * k + s) * 3 + c] - 0.5);
        }
      }
      let trace = 0;
      for (let a = 0; a < basisCount; a++) {
        for (let b = 0; b < a; b++) normal[b * basisCount + a] = normal[a * basisCount + b];
        trace += normal[a * basisCount + a];
      }
      if (settings.ridge > 0 && basisCount > 1) {
        const ridge = (settings.ridge * trace) / basisCount;
        for (let a = 1; a < basisCount; a++) normal[a * basisCount + a] += ridge;
        trace += ridge * (basisCount - 1);
      }
      const floor = 1e-9 * Math.max(trace, 1e-300);
      for (let a = 0; a < basisCount; a++) normal[a * basisCount + a] += floor;
      solveSpd(normal, target, basisCount);
      for (let a = 0; a < 16; a++) scratch4[a] = moment[16 * s + a];
      principalAxis4(scratch4, axis);
      out.anchorIndex.push(i);
      out.positions.push(centers[3 * s], centers[3 * s + 1], centers[3 * s + 2]);
      for (let a = 0; a < basisCount * 3; a++) out.sh.push(target[a]);
      const opacity = Math.min(Math.max(weightSum[s] / onCount[s], 0), MAX_OPACITY);
      out.opacity.push(Math.log(opacity) - Math.log1p(-opacity));
      for (let a = 0; a < 3; a++) out.scales.push(logScaleSum[3 * s + a] / weightSum[s]);
      out.rotations.push(axis[0], axis[1], axis[2], axis[3]);
    }
    if (options.onProgress && ((i + 1) % block === 0 || i + 1 === m)) options.onProgress((i + 1) / m);
  }
  return assemble(anchors, out, basisCount);
}

function assemble(anchors, out, basisCount) {
  const n = out.anchorIndex.length;
  const sh = out.sh;
  const shDc = new Float32Array(3 * n), shRest = new Float32Array(3 * n * (basisCount - 1));
  for (let g = 0; g < n; g++) {
    for (let c = 0; c < 3; c++) shDc[3 * g + c] = sh[g * basisCount * 3 + c];
    for (let a = 1; a < basisCount; a++) {
      for (let c = 0; c < 3; c++) shRest[(g * (basisCount - 1) + a - 1) * 3 + c] = sh[(g * basisCount + a) * 3 + c];
    }
  }
  const anchorIndex = Int32Array.from(out.anchorIndex);
  let semantic = null, labels = null;
  if (anchors.semantic && anchors.semanticNames && anchors.semanticNames.length) {
    const s = anchors.semanticNames.length;
    semantic = new Float32Array(n * s);
    for (let g = 0; g < n; g++) semantic.set(anchors.semantic.subarray(anchorIndex[g] * s, anchorIndex[g] * s + s), g * s);
  }
  if (anchors.labels) {
    labels = new Int32Array(n);
    for (let g = 0; g < n; g++) labels[g] = anchors.labels[anchorIndex[g]];
  }
  return {
    count: n,
    positions: Float32Array.from(out.positions),
    sh_dc: shDc,
    sh_rest: shRest,
    opacity: Float32Array.from(out.opacity),
    scales: Float32Array.from(out.scales),
    rotations: Float32Array.from(out.rotations),
    semantic,
    semanticNames: semantic ? anchors.semanticNames : [],
    labels,
    instances: null,
    anchorIndex,
    complete: true,
    shCoefficients: basisCount - 1,
  };
}
