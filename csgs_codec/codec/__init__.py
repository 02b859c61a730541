"""Encoder and Decoder: orchestration of scene, format, entropy and model layers."""
