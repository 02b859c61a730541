"""Numerical stability tests: extreme and degenerate scenes through the codec, PLY and renderer."""
