"""Cross-machine determinism: decode the conformance vectors under other thread counts, BLAS
kernels and torch settings, and compare every output with its recorded SHA-256."""
