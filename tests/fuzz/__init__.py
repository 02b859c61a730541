"""Decoder fuzzing: mutated .csgs files must decode or fail with FormatError, within bounds."""
