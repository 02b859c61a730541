/**
 * Worker thread of parallel_node.mjs: takes tasks (color streams, geometry) from the shared
 * queue it is sent, decodes them into the shared output arrays and reports, per task it took,
 * success or the error it raised.
 */

import { parentPort, workerData } from 'node:worker_threads';

import { FormatError } from './errors.mjs';
import { setRangeCoder } from './range_decoder.mjs';
import { claimTasks } from './parallel_node.mjs';
import { decodeTask } from './scene.mjs';
import { loadTables } from './tables_node.mjs';

let tables = null;
setRangeCoder(workerData.rangeCoder);

parentPort.on('message', (job) => {
  tables = tables || loadTables();
  const payloads = new Map();
  for (const entry of job.entries) payloads.set(entry.index, job.data.subarray(entry.offset + 8, entry.offset + 8 + entry.length));
  const prep = { container: { toc: { entries: job.entries }, payloads }, header: job.header, family: tables.family, sine: tables.sine };
  const results = claimTasks(job.queue, job.counter, (task) => {
    try {
      const value = decodeTask(prep, job.out, task);
      return { ok: true, axis: task === 'ROTN' ? value : null };
    } catch (err) {
      return err instanceof FormatError
        ? { ok: false, name: 'FormatError', detail: err.detail, chunk: err.chunk, offset: err.offset }
        : { ok: false, name: 'Error', detail: String(err && err.stack ? err.stack : err) };
    }
  });
  parentPort.postMessage(results);
});
