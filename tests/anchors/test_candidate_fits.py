"""Small anchor scenes try several hyperprior widths per layer and keep the smallest coding."""

from __future__ import annotations

from csgs_codec.codec import anchor_encoder as ae
from csgs_codec.model.anchor_hyperprior import FitSettings
from csgs_codec.scene.synthetic_anchors import synthetic_anchor_scene

COLOR = ("AHYP", "ACRM", "AFEA", "AOFF", "ASCL")
SEMANTIC = ("SHYP", "ASEM")
QUICK = FitSettings(hidden=16, carm_hidden=8, steps=30, batch=256)


def _layer_bytes(chunks: dict[str, int]) -> tuple[int, int]:
    return sum(chunks[c] for c in COLOR), sum(chunks[c] for c in SEMANTIC)


def test_small_scenes_try_each_narrow_width_below_the_configured_one():
    fits = ae.AnchorEncoder(5, fit=QUICK)._candidate_fits(100)
    assert [f.hidden for f in fits] == [16, *ae.NARROW_WIDTHS]
    assert all(f.carm_hidden <= f.hidden for f in fits)
    assert [f.hidden for f in ae.AnchorEncoder(5, fit=QUICK)._candidate_fits(
        ae.NARROW_FIT_ANCHORS)] == [16]


def test_each_layer_keeps_its_smallest_candidate(monkeypatch):
    scene = synthetic_anchor_scene(3, 40, feat_dim=8, n_offsets=3, with_mlps=False)
    chosen = _layer_bytes(ae.AnchorEncoder(5, fit=QUICK).encode_with_report(scene).chunk_bytes)
    candidates = ae.AnchorEncoder(5, fit=QUICK)._candidate_fits(len(scene))
    assert len(candidates) == 3
    monkeypatch.setattr(ae, "NARROW_FIT_ANCHORS", 0)  # one candidate per encode below
    alone = [_layer_bytes(ae.AnchorEncoder(5, fit=f).encode_with_report(scene).chunk_bytes)
             for f in candidates]
    assert chosen[0] == min(a[0] for a in alone)
    assert chosen[1] == min(a[1] for a in alone)
