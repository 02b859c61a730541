"""Semantic features at work: click selection of objects and its scoring against labels."""

from csgs_codec.semantic.selection import (
    DEFAULT_THRESHOLD,
    MODES,
    ClickSelection,
    FeatureMap,
    click_selection,
    render_feature_map,
    select_at_click,
    selected_gaussians,
)

__all__ = ["DEFAULT_THRESHOLD", "MODES", "ClickSelection", "FeatureMap", "click_selection",
           "render_feature_map", "select_at_click", "selected_gaussians"]
