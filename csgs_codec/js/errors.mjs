/**
 * Errors of the JavaScript receiver.
 *
 * FormatError: the file is invalid (spec/FORMAT.md); it names the chunk type (null for the
 * header and TOC before an entry is known) and the absolute byte offset (null where the
 * problem has no single place, e.g. a missing chunk).
 * UnsupportedError: a valid kind of file this decoder does not implement (anchor scenes).
 */

export class FormatError extends Error {
  /**
   * @param {string} message what is wrong
   * @param {{chunk?: string|null, offset?: number|null}} where chunk type and byte offset
   */
  constructor(message, { chunk = null, offset = null } = {}) {
    const place = `${chunk === null ? 'container' : `chunk ${chunk}`}` +
      `${offset === null ? '' : `, offset ${offset}`}`;
    super(`${message} (${place})`);
    this.name = 'FormatError';
    this.chunk = chunk;
    this.offset = offset;
    this.detail = message;
  }
}

export class UnsupportedError extends Error {
  /** @param {string} message what this decoder does not implement */
  constructor(message) {
    super(`unsupported: ${message}`);
    this.name = 'UnsupportedError';
  }
}
