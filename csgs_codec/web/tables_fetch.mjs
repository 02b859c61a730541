/**
 * The frozen tables (spec/FORMAT.md §16.2.1, §16.2.2) in a browser: fetched from the
 * package's entropy/data/ folder once per thread and checked against their SHA-256.
 */

import { GAUSSIAN_V1_SHA256, SINE_V1_SHA256, parseGaussianFamily, parseSineTable } from '../js/tables.mjs';

const TABLES_URL = new URL('../entropy/data/', import.meta.url);
let tablesPromise = null;

/** SHA-256 of ``bytes`` as lowercase hex. */
export async function sha256Hex(bytes) {
  const digest = new Uint8Array(await crypto.subtle.digest('SHA-256', bytes));
  return Array.from(digest, (b) => b.toString(16).padStart(2, '0')).join('');
}

/** {family, sine}: the parsed tables, fetched the first time. */
export function loadTables() {
  tablesPromise ??= (async () => {
    const get = async (name, expected) => {
      const response = await fetch(new URL(name, TABLES_URL));
      if (!response.ok) throw new Error(`cannot fetch the frozen table ${name}: HTTP ${response.status}`);
      const bytes = new Uint8Array(await response.arrayBuffer());
      if (await sha256Hex(bytes) !== expected) throw new Error(`the frozen table ${name} has the wrong SHA-256`);
      return bytes;
    };
    const [family, sine] = await Promise.all([get('gaussian_v1.bin', GAUSSIAN_V1_SHA256), get('sine_v1.bin', SINE_V1_SHA256)]);
    return { family: parseGaussianFamily(family), sine: parseSineTable(sine) };
  })();
  return tablesPromise;
}
