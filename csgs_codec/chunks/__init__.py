"""Chunk payloads of spec/FORMAT.md §12, one module per chunk family, each holding both
directions: the bytes the encoder writes and the reader that checks and parses them.

What goes into a chunk (which points are far, which steps a stream uses) is decided by the
encoder in :mod:`csgs_codec.codec`; the modules here only lay out and read bytes.
"""
