/**
 * Worker thread of a Node decode lane (parallel_node.mjs): serves lane_server.mjs over the
 * thread's port, with the frozen tables read from the package.
 */

import { parentPort, workerData } from 'node:worker_threads';

import { setIntNetKernel } from './intnet.mjs';
import { serveLane } from './lane_server.mjs';
import { setRangeCoder } from './range_decoder.mjs';
import { loadTables } from './tables_node.mjs';

setRangeCoder(workerData.rangeCoder);
setIntNetKernel(workerData.rangeCoder);
serveLane({
  post: (message, transfer) => parentPort.postMessage(message, transfer),
  listen: (handler) => parentPort.on('message', handler),
}, loadTables);
