/**
 * Click selection with the rules of `csgs select` (csgs_codec/semantic/selection.py).
 *
 * "instance" (used whenever the scene has instances: labels, or features with at most 255
 * distinct rows and at least 4 Gaussians per row on average, as `csgs segment` writes): the
 * instance whose Gaussians carry the most compositing weight at the clicked pixel is selected
 * whole. Scenes with continuous features (trained, not segmented) have no instances and use
 * "cosine", as Python's "instance" mode does for them.
 *
 * "cosine": the semantic features are alpha-composited at the clicked pixel exactly as the
 * project rasterizer composites color (EWA projection with the 0.3 px^2 low-pass, alpha
 * clamped to 0.99, contributions below 1/255 skipped, front to back by camera depth, stopping
 * before transmittance falls below 1e-4), divided by the pixel's accumulated opacity and
 * normalised; every Gaussian whose unit feature has cosine >= threshold with it is selected.
 * A pixel with accumulated opacity below 0.05 hits nothing.
 */

export const DEFAULT_THRESHOLD = 0.9;
export const MIN_CLICK_ALPHA = 0.05;
/** Most distinct feature rows read as instances (selection.py MAX_INSTANCES). */
export const MAX_INSTANCES = 255;
/** Gaussians per distinct row needed, on average (selection.py MIN_INSTANCE_SIZE). */
export const MIN_INSTANCE_SIZE = 4;
const LOW_PASS_VARIANCE = 0.3;
const ALPHA_THRESHOLD = 1 / 255;
const MAX_ALPHA = 0.99;
const TRANSMITTANCE_STOP = 1e-4;
const JACOBIAN_FOV_MARGIN = 1.3;

/**
 * The Gaussians that contribute at pixel (column, row) and their weights alpha * T.
 * @returns {{index: Int32Array, weight: Float64Array, alpha: number, hits: number}}
 */
export function weightsAtPixel(scene, camera, column, row) {
  const hits = pixelHits(scene, camera, column, row);
  const index = [];
  const weight = [];
  let transmittance = 1;
  for (const [, alpha, i] of hits) {
    const after = transmittance * (1 - alpha);
    if (after < TRANSMITTANCE_STOP) break;
    index.push(i);
    weight.push(alpha * transmittance);
    transmittance = after;
  }
  return { index: Int32Array.from(index), weight: Float64Array.from(weight), alpha: 1 - transmittance, hits: hits.length };
}

/**
 * The alpha and opacity-weighted feature sum at pixel (column, row).
 * @param {object} scene decoded arrays: positions (N x 3), scales (N x 3 log), rotations
 *   (N x 4, w x y z), opacity (N logits)
 * @param {Float32Array} features N x S
 * @param {number} channels S
 * @param {object} camera project-convention camera (camera_rig.mjs)
 * @returns {{feature: Float64Array, alpha: number, hits: number}}
 */
export function compositeAtPixel(scene, features, channels, camera, column, row) {
  const { index, weight, alpha, hits } = weightsAtPixel(scene, camera, column, row);
  const feature = new Float64Array(channels);
  for (let k = 0; k < index.length; k++) {
    const i = index[k];
    for (let s = 0; s < channels; s++) feature[s] += weight[k] * features[i * channels + s];
  }
  return { feature, alpha, hits };
}

/** [depth, alpha, index] of every Gaussian whose alpha at the pixel reaches 1/255, sorted
 * near to far (stable: ties keep index order, as the reference's stable depth sort). */
function pixelHits(scene, camera, column, row) {
  const { positions, scales, rotations, opacity } = scene;
  const m = camera.world_to_camera;
  const { fx, fy, cx, cy } = camera;
  const px = column + 0.5;
  const py = row + 0.5;
  const limXn = JACOBIAN_FOV_MARGIN * cx / fx;
  const limXp = JACOBIAN_FOV_MARGIN * (camera.width - cx) / fx;
  const limYn = JACOBIAN_FOV_MARGIN * cy / fy;
  const limYp = JACOBIAN_FOV_MARGIN * (camera.height - cy) / fy;
  const near = camera.near_plane;
  const hits = [];
  const n = opacity.length;
  for (let i = 0; i < n; i++) {
    const X = positions[3 * i];
    const Y = positions[3 * i + 1];
    const Z = positions[3 * i + 2];
    const x = m[0] * X + m[1] * Y + m[2] * Z + m[3];
    const y = m[4] * X + m[5] * Y + m[6] * Z + m[7];
    const z = m[8] * X + m[9] * Y + m[10] * Z + m[11];
    if (!(z > near)) continue;
    const op = 1 / (1 + Math.exp(-opacity[i]));
    if (!(op > ALPHA_THRESHOLD)) continue;
    const u = fx * x / z + cx;
    const v = fy * y / z + cy;
    const tx = z * Math.min(Math.max(x / z, -limXn), limXp);
    const ty = z * Math.min(Math.max(y / z, -limYn), limYp);
    // J W: the perspective Jacobian times the camera rotation (2 x 3).
    const j00 = fx / z; const j02 = -fx * tx / (z * z);
    const j11 = fy / z; const j12 = -fy * ty / (z * z);
    const a0 = j00 * m[0] + j02 * m[8]; const a1 = j00 * m[1] + j02 * m[9]; const a2 = j00 * m[2] + j02 * m[10];
    const b0 = j11 * m[4] + j12 * m[8]; const b1 = j11 * m[5] + j12 * m[9]; const b2 = j11 * m[6] + j12 * m[10];
    // M = R(q) diag(exp(scale)); screen rows = (J W) M.
    let qw = rotations[4 * i]; let qx = rotations[4 * i + 1]; let qy = rotations[4 * i + 2]; let qz = rotations[4 * i + 3];
    const qn = Math.hypot(qw, qx, qy, qz);
    if (qn > 0) { qw /= qn; qx /= qn; qy /= qn; qz /= qn; } else { qw = 1; }
    const s0 = Math.exp(scales[3 * i]); const s1 = Math.exp(scales[3 * i + 1]); const s2 = Math.exp(scales[3 * i + 2]);
    const r00 = 1 - 2 * (qy * qy + qz * qz); const r01 = 2 * (qx * qy - qw * qz); const r02 = 2 * (qx * qz + qw * qy);
    const r10 = 2 * (qx * qy + qw * qz); const r11 = 1 - 2 * (qx * qx + qz * qz); const r12 = 2 * (qy * qz - qw * qx);
    const r20 = 2 * (qx * qz - qw * qy); const r21 = 2 * (qy * qz + qw * qx); const r22 = 1 - 2 * (qx * qx + qy * qy);
    const p0 = (a0 * r00 + a1 * r10 + a2 * r20) * s0; const p1 = (a0 * r01 + a1 * r11 + a2 * r21) * s1; const p2 = (a0 * r02 + a1 * r12 + a2 * r22) * s2;
    const q0 = (b0 * r00 + b1 * r10 + b2 * r20) * s0; const q1 = (b0 * r01 + b1 * r11 + b2 * r21) * s1; const q2 = (b0 * r02 + b1 * r12 + b2 * r22) * s2;
    const a = p0 * p0 + p1 * p1 + p2 * p2 + LOW_PASS_VARIANCE;
    const b = p0 * q0 + p1 * q1 + p2 * q2;
    const c = q0 * q0 + q1 * q1 + q2 * q2 + LOW_PASS_VARIANCE;
    const det = a * c - b * b;
    if (!(det > 0)) continue;
    const dx = px - u;
    const dy = py - v;
    const power = -0.5 * (c * dx * dx + a * dy * dy) / det + b * dx * dy / det;
    const alpha = Math.min(MAX_ALPHA, op * Math.exp(power));
    if (!(alpha >= ALPHA_THRESHOLD)) continue;
    hits.push([z, alpha, i]);
  }
  hits.sort((p, q) => p[0] - q[0]);
  return hits;
}

/**
 * The instance of every Gaussian: the labels when there are any, else the distinct rows of
 * the features when there are at most MAX_INSTANCES of them and at least MIN_INSTANCE_SIZE
 * Gaussians per row on average; else null (select by cosine).
 * @returns {{ids: Int32Array, source: string}|null}
 */
export function elementInstances(labels, features, channels) {
  if (labels) return { ids: Int32Array.from(labels), source: 'labels' };
  if (!features || !channels) return null;
  const n = features.length / channels;
  const rows = new Map();
  const ids = new Int32Array(n);
  const bits = new Uint32Array(features.buffer, features.byteOffset, features.length);
  for (let i = 0; i < n; i++) {
    const key = Array.from(bits.subarray(i * channels, (i + 1) * channels)).join(',');
    let id = rows.get(key);
    if (id === undefined) {
      if (rows.size >= MAX_INSTANCES) return null;
      id = rows.size;
      rows.set(key, id);
    }
    ids[i] = id;
  }
  if (rows.size * MIN_INSTANCE_SIZE > n) return null;
  return { ids, source: 'features' };
}

/**
 * Select the instance carrying the most weight at pixel (column, row), whole.
 * @returns {{mask: Uint8Array, count: number, alpha: number, instance: number}} or throws
 *   Error with a message for a click on the background
 */
export function selectInstanceAtPixel(scene, ids, camera, column, row) {
  const { index, weight, alpha } = weightsAtPixel(scene, camera, column, row);
  if (!(alpha >= MIN_CLICK_ALPHA)) {
    throw new Error(`nothing under the click at pixel (${column}, ${row}): accumulated opacity ${alpha.toPrecision(3)} is below ${MIN_CLICK_ALPHA}`);
  }
  const carried = new Map();
  for (let k = 0; k < index.length; k++) {
    const id = ids[index[k]];
    carried.set(id, (carried.get(id) || 0) + weight[k]);
  }
  let chosen = null;
  for (const id of [...carried.keys()].sort((a, b) => a - b)) {
    if (chosen === null || carried.get(id) > carried.get(chosen)) chosen = id;
  }
  const mask = new Uint8Array(ids.length);
  let count = 0;
  for (let i = 0; i < ids.length; i++) if (ids[i] === chosen) { mask[i] = 1; count++; }
  return { mask, count, alpha, instance: chosen };
}

/**
 * Select by the feature under pixel (column, row).
 * @returns {{mask: Uint8Array, count: number, alpha: number}} or throws Error with a
 *   message for a click on the background or on a zero feature
 */
export function selectAtPixel(scene, features, channels, camera, column, row, threshold = DEFAULT_THRESHOLD) {
  const { feature, alpha } = compositeAtPixel(scene, features, channels, camera, column, row);
  if (!(alpha >= MIN_CLICK_ALPHA)) {
    throw new Error(`nothing under the click at pixel (${column}, ${row}): accumulated opacity ${alpha.toPrecision(3)} is below ${MIN_CLICK_ALPHA}`);
  }
  let norm = 0;
  for (let s = 0; s < channels; s++) { feature[s] /= alpha; norm += feature[s] * feature[s]; }
  norm = Math.sqrt(norm);
  if (!(Number.isFinite(norm) && norm > 0)) throw new Error(`the semantic feature under pixel (${column}, ${row}) is zero; there is no direction to match`);
  for (let s = 0; s < channels; s++) feature[s] /= norm;
  const n = features.length / channels;
  const mask = new Uint8Array(n);
  let count = 0;
  for (let i = 0; i < n; i++) {
    let length = 0;
    let score = 0;
    for (let s = 0; s < channels; s++) {
      const f = features[i * channels + s];
      length += f * f;
      score += f * feature[s];
    }
    length = Math.sqrt(length);
    if (length > 0 && Number.isFinite(length) && score / length >= threshold) { mask[i] = 1; count++; }
  }
  return { mask, count, alpha };
}
