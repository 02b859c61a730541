/**
 * A Web Worker that decodes tasks for the viewer's decode worker (decode_worker.mjs): a
 * decode lane (../js/lane_server.mjs) with the tables fetched from the package.
 */

import './receiver_modules.mjs';
import { serveLane } from '../js/lane_server.mjs';
import { loadTables } from './tables_fetch.mjs';

serveLane({
  post: (message, transfer) => self.postMessage(message, transfer),
  listen: (handler) => { self.onmessage = (event) => handler(event.data); },
}, loadTables);
