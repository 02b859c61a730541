/**
 * A decode lane on another thread: the runner (decode_runner.mjs) posts it a scene's bytes
 * once and then tasks with their inputs; the thread (lane_server.mjs) answers each task with
 * its outputs, transferred, or with its error. The same lane works over a Node worker thread
 * and a browser Web Worker: ``port`` hides which.
 */

import { FormatError, UnsupportedError } from './errors.mjs';

/** An error as it crossed from the lane's thread (see lane_server.mjs errorRecord). */
export function errorFromRecord(record) {
  if (record.name === 'FormatError') return new FormatError(record.detail, { chunk: record.chunk, offset: record.offset });
  if (record.name === 'UnsupportedError') return new UnsupportedError(record.detail);
  return new Error(record.detail);
}

export class RemoteLane {
  /**
   * @param {{post: (message: object) => void, listen: (handler: (message: object) => void) => void,
   *   close: () => void}} port the thread's message port
   */
  constructor(port) {
    this.port = port;
    this.waiting = new Map();
    this.nextId = 0;
    this.sentData = null;
    this.openedPlan = null;
    port.listen((message) => {
      const settle = this.waiting.get(message.id);
      if (!settle) return;
      this.waiting.delete(message.id);
      if (message.ok) settle.resolve(message.outputs);
      else settle.reject(errorFromRecord(message.error));
    });
  }

  /** Tell the thread about ``plan``'s scene (its file bytes, the first time they are used;
   * or, for a container read frame by frame, its payloads and the file's size). */
  open(plan) {
    if (this.openedPlan === plan) return;
    const { data, entries, layers } = plan.source;
    const message = { kind: 'scene', entries, layers: [...layers] };
    if (plan.source.payloads) {
      message.payloads = plan.source.payloads;
      message.size = plan.source.size;
    } else if (this.sentData !== data) {
      message.data = data;
      this.sentData = data;
    }
    this.port.post(message);
    this.openedPlan = plan;
  }

  /** A task's outputs, computed on the lane's thread. */
  run(plan, task, inputs) {
    this.open(plan);
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.waiting.set(id, { resolve, reject });
      this.port.post({ kind: 'task', id, task, inputs });
    });
  }

  /** Stop the thread; tasks still waiting fail. */
  close() {
    for (const settle of this.waiting.values()) settle.reject(new Error('the decode lane was closed'));
    this.waiting.clear();
    return this.port.close();
  }
}
