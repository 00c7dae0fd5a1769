"""Granular resistive force theory: media, per-facet stress models, batched wrench engine."""
