"""Conversions of anchor scenes into standard Gaussian scenes (the bake a receiver without
the Scaffold-GS MLPs needs)."""
