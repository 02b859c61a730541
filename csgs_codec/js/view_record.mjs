/**
 * The optional vdis record (spec/FORMAT.md §12.21): which viewing distribution an encoder's
 * view pruning followed. Informative: nothing decoded depends on it, so a record this
 * receiver cannot read (an unknown version, say) is skipped, never a reason to reject a file.
 */

import { ByteReader } from './bytes.mjs';
import { FormatError } from './errors.mjs';

const VERSION = 1;
const SOURCES = ['default-sphere', 'cameras'];
const MAX_COUNT = 2 ** 32;
const MAX_DESCRIPTION = 256;

/**
 * Parse a vdis payload; FormatError (naming vdis) when it breaks §12.21.
 * @returns {{source: string, count: number, leftOut: number, description: string}}
 */
export function parseViewRecord(data, offset) {
  const r = new ByteReader(data, offset, 'vdis');
  const versionAt = r.offset;
  const version = r.u8('version');
  if (version !== VERSION) throw r.error(`unknown view-distribution version ${version}`, versionAt);
  const sourceAt = r.offset;
  const code = r.u8('source');
  if (code >= SOURCES.length) throw r.error(`unknown view source ${code}`, sourceAt);
  const count = r.varint('view_count', MAX_COUNT);
  const leftOut = r.varint('left_out', MAX_COUNT);
  const textAt = r.offset;
  const raw = r.byteString('description', MAX_DESCRIPTION);
  let description;
  try {
    description = new TextDecoder('utf-8', { fatal: true, ignoreBOM: true }).decode(raw);
  } catch {
    throw r.error('description is not UTF-8', textAt);
  }
  r.expectEnd('the view-distribution record');
  return { source: SOURCES[code], count, leftOut, description };
}

/**
 * The scene's viewing distribution for the decode result's metadata: ``views`` (the record,
 * or null without a readable one) and ``skipped`` (the FormatError message of a record that
 * could not be read, else null).
 */
export function readViews(container) {
  const entry = container.toc.entries.find((e) => e.type === 'vdis');
  if (!entry || !container.payloads.has(entry.index)) return { views: null, skipped: null };
  try {
    return { views: parseViewRecord(container.payloads.get(entry.index), entry.offset + 8), skipped: null };
  } catch (err) {
    if (err instanceof FormatError) return { views: null, skipped: err.message };
    throw err;
  }
}
