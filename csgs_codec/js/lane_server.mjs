/**
 * The thread side of a decode lane (lane_client.mjs): keeps the scene it was sent, runs the
 * tasks it is sent (decode_tasks.mjs) and answers each with its outputs, their buffers
 * transferred, or with its error as a record. worker_node.mjs (Node) and
 * ../web/lane_worker.mjs (browser) serve it over their thread's port.
 */

import { runTask } from './decode_tasks.mjs';
import { FormatError, UnsupportedError } from './errors.mjs';
import { prepareContainer } from './scene.mjs';

/** A plain record of an error, able to cross between threads. */
export function errorRecord(err) {
  if (err instanceof FormatError) return { name: 'FormatError', detail: err.detail, chunk: err.chunk, offset: err.offset };
  if (err instanceof UnsupportedError) return { name: 'UnsupportedError', detail: err.message.replace(/^unsupported: /, '') };
  return { name: 'Error', detail: String(err && err.stack ? err.stack : err) };
}

/** The distinct ArrayBuffers under ``value`` (typed arrays in objects, arrays and maps). */
function buffersOf(value, found = new Set()) {
  if (ArrayBuffer.isView(value)) {
    const whole = value.byteOffset === 0 && value.byteLength === value.buffer.byteLength;
    if (whole && value.buffer instanceof ArrayBuffer) found.add(value.buffer); // else copied
  } else if (value instanceof Map) {
    for (const item of value.values()) buffersOf(item, found);
  } else if (value && typeof value === 'object') {
    for (const item of Object.values(value)) buffersOf(item, found);
  }
  return found;
}

/**
 * Serve a lane over ``port``.
 * @param {{post: (message: object, transfer: ArrayBuffer[]) => void,
 *   listen: (handler: (message: object) => void) => void}} port
 * @param {() => Promise<{family: object, sine: Int32Array}>|{family: object, sine: Int32Array}} loadTables
 */
export function serveLane(port, loadTables) {
  let tables = null;
  let data = null;
  let prep = null;
  let failure = null; // the scene could not be prepared: every task of it fails so
  let queue = Promise.resolve();
  const handle = async (message) => {
    tables ??= await loadTables();
    if (message.kind === 'scene') {
      if (message.data) data = message.data;
      failure = null;
      try {
        let payloads = message.payloads;
        if (!payloads) {
          payloads = new Map();
          for (const e of message.entries) payloads.set(e.index, data.subarray(e.offset + 8, e.offset + 8 + e.length));
        }
        const container = { toc: { entries: message.entries }, payloads };
        prep = prepareContainer(container, message.size ?? data.length, new Set(message.layers), { tables });
      } catch (err) {
        failure = errorRecord(err);
      }
      return;
    }
    if (message.kind !== 'task') return;
    if (failure) {
      port.post({ id: message.id, ok: false, error: failure }, []);
      return;
    }
    try {
      const outputs = runTask(prep, message.task, message.inputs);
      port.post({ id: message.id, ok: true, outputs }, [...buffersOf(outputs)]);
    } catch (err) {
      port.post({ id: message.id, ok: false, error: errorRecord(err) }, []);
    }
  };
  // In arrival order, even while the tables load.
  port.listen((message) => { queue = queue.then(() => handle(message)); });
}
