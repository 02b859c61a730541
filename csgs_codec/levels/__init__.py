"""Levels of detail: coarser versions of a scene made by merging neighbouring Gaussians
(FORMAT §12.22, tile index version 2)."""
