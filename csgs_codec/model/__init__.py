"""Torch models: hyperprior, integer export, Scaffold-GS MLPs (encoder and training side)."""
