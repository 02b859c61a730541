"""Entropy layer (numpy + constriction, never torch): frozen tables, residual coding, integer
networks, geometry coding. spec/FORMAT.md §15-§16 defines the bytes and the arithmetic."""

from csgs_codec.entropy.intnet import IntLayer, IntMLP, positional_embedding
from csgs_codec.entropy.residual import (
    STEP_COUNT,
    decode_residuals,
    decode_symbols,
    encode_residuals,
    encode_symbols,
    from_grid,
    quantize,
    reconstruct,
    reconstructed_values,
    step_index,
    step_size,
    to_grid,
)
from csgs_codec.entropy.tables import gaussian_family, scale_index, sine_table

__all__ = [
    "STEP_COUNT",
    "IntLayer",
    "IntMLP",
    "decode_residuals",
    "decode_symbols",
    "encode_residuals",
    "encode_symbols",
    "from_grid",
    "gaussian_family",
    "positional_embedding",
    "quantize",
    "reconstruct",
    "reconstructed_values",
    "scale_index",
    "sine_table",
    "step_index",
    "step_size",
    "to_grid",
]
