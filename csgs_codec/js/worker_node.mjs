/**
 * Worker thread of parallel_node.mjs: decodes the tasks (colour streams, geometry) it is sent
 * into the shared output arrays and reports, per task, success or the error it raised.
 */

import { parentPort, workerData } from 'node:worker_threads';

import { FormatError } from './errors.mjs';
import { setRangeCoder } from './range_decoder.mjs';
import { decodeTask } from './scene.mjs';
import { loadTables } from './tables_node.mjs';

let tables = null;
setRangeCoder(workerData.rangeCoder);

parentPort.on('message', (job) => {
  tables = tables || loadTables();
  const payloads = new Map();
  for (const entry of job.entries) payloads.set(entry.index, job.data.subarray(entry.offset + 8, entry.offset + 8 + entry.length));
  const prep = { container: { toc: { entries: job.entries }, payloads }, header: job.header, family: tables.family, sine: tables.sine };
  const results = {};
  for (const task of job.tasks) {
    try {
      const value = decodeTask(prep, job.out, task);
      results[task] = { ok: true, axis: task === 'ROTN' ? value : null };
    } catch (err) {
      results[task] = err instanceof FormatError
        ? { ok: false, name: 'FormatError', detail: err.detail, chunk: err.chunk, offset: err.offset }
        : { ok: false, name: 'Error', detail: String(err && err.stack ? err.stack : err) };
    }
  }
  parentPort.postMessage(results);
});
