"""PLY input and output for Gaussian scenes (the one import path callers need)."""

from csgs_codec.atomic_write import write_atomically
from csgs_codec.interchange.ply_reader import (
           PlyReport,
           parse_ply_bytes,
           read_ply,
           read_ply_with_report,
)
from csgs_codec.interchange.ply_writer import ply_bytes, write_ply

__all__ = ["read_ply", "read_ply_with_report", "parse_ply_bytes", "PlyReport", "write_ply",
           "ply_bytes", "write_atomically"]
