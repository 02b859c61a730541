"""The determinism script decodes conformance vectors bit-identically across thread counts,
BLAS kernels and torch settings, and reports a changed output as a failure."""

from __future__ import annotations

import json
import os
import shutil

import pytest

from tests.conformance import VECTORS_DIR
from tests.determinism.check_vectors import Config, blas_variants, check, default_configs, main
from tests.determinism.vector_cases import FAMILIES, json_digest, vector_cases

#: A fast subset: every small family plus the small scene and anchor vectors.
SUBSET = ["container", "entropy", "geometry", "scenes/semantic_small", "scenes/three_points",
          "anchors/anchors_semantic_q5"]


def _quiet(*_args) -> None:
    """Swallow the script's progress lines."""


def test_cases_cover_every_family_and_both_layer_choices():
    ids = [case.id for case in vector_cases(VECTORS_DIR)]
    present = {family for family in FAMILIES if (VECTORS_DIR / family).is_dir()}
    assert {"container", "entropy", "geometry", "scenes"} <= present
    assert {case_id.split("/")[0] for case_id in ids} == present
    assert {"scenes/donut_q3[color]", "scenes/donut_q3[color,semantic]",
            "scenes/truncated_label_payload[color]"} <= set(ids)
    assert not any(case_id.startswith("scenes/missing_opacity_chunk") for case_id in ids)


def test_expected_digests_come_from_the_vector_records():
    doc = json.loads((VECTORS_DIR / "scenes" / "semantic_small.json").read_text())
    cases = {c.id: c for c in vector_cases(VECTORS_DIR, ["scenes/semantic_small"])}
    assert cases["scenes/semantic_small[color,semantic]"].expected == doc["reads"][1]["ply_sha256"]
    residual = json.loads((VECTORS_DIR / "entropy" / "residual_single.json").read_text())
    (case,) = vector_cases(VECTORS_DIR, ["entropy/residual_single"])
    assert case.expected == json_digest(residual["decoded"])


def test_the_torch_free_anchor_digest_equals_the_conformance_definition():
    path = VECTORS_DIR / "anchors" / "anchors_semantic_q5.csgs"
    if not path.exists():
        pytest.skip("no anchor vectors in this checkout")
    from csgs_codec.codec.anchor_decoder import AnchorDecoder
    from tests.conformance.anchors import anchor_digest
    from tests.determinism.vector_cases import anchor_scene_digest

    data = path.read_bytes()
    scene = AnchorDecoder().decode(data, layers="color,semantic")
    assert anchor_scene_digest(scene) == anchor_digest(scene)


def test_subset_decodes_identically_across_threads_torch_and_blas_kernels():
    configs = [Config(1, "none"), Config(2, "on"), Config(2, "off")]
    configs += [Config(1, "none", kind) for kind in blas_variants()[:1]]
    ok, results = check(VECTORS_DIR, configs, SUBSET, echo=_quiet)
    assert [r.failure for r in results] == [None] * len(configs)
    assert ok
    torch_on = results[1].environment
    assert torch_on["torch_loaded"] and torch_on["deterministic"] is True
    assert results[2].environment["deterministic"] is False
    assert not results[0].environment["torch_loaded"]
    has_anchors = (VECTORS_DIR / "anchors").is_dir()
    assert has_anchors == any(c.startswith("anchors/") for c in results[0].digests)


def test_a_changed_output_is_reported_as_a_mismatch(tmp_path):
    vectors = tmp_path / "vectors"
    shutil.copytree(VECTORS_DIR / "entropy", vectors / "entropy")
    path = vectors / "entropy" / "residual_single.json"
    doc = json.loads(path.read_text())
    doc["decoded"][0] += 1
    path.write_text(json.dumps(doc))
    lines = []
    ok, _ = check(vectors, [Config(1, "none")], ["entropy/residual"], echo=lines.append)
    assert not ok
    assert any(line.startswith("MISMATCH") and "entropy/residual_single" in line
               for line in lines)


def test_command_exits_nonzero_on_a_mismatch_and_zero_when_all_match(tmp_path, capsys):
    vectors = tmp_path / "vectors"
    shutil.copytree(VECTORS_DIR / "geometry", vectors / "geometry")
    args = ["--vectors", str(vectors), "--threads", "1", "--torch", "none",
            "--no-blas-variants"]
    assert main(args) == 0
    path = vectors / "geometry" / "single_point.json"
    doc = json.loads(path.read_text())
    doc["points"][0][0] ^= 1
    path.write_text(json.dumps(doc))
    assert main(args) == 1
    assert "determinism check FAILED" in capsys.readouterr().out


def test_default_configurations_cover_three_thread_counts_and_three_torch_modes():
    configs = default_configs([1, 2, 16], ["none", "on", "off"], cuda=True,
                              with_blas_variants=True)
    plain = {(c.threads, c.torch) for c in configs if c.coretype is None}
    assert {(t, m) for t in (1, 2, 16) for m in ("none", "on", "off")} <= plain
    assert {c.torch for c in configs} == {"none", "on", "off", "cuda"}


@pytest.mark.slow
def test_every_vector_decodes_identically_in_every_default_configuration():
    threads = sorted({1, 2, os.cpu_count() or 1})
    configs = default_configs(threads, ["none", "on", "off"], cuda=False,
                              with_blas_variants=True)
    ok, results = check(VECTORS_DIR, configs, echo=_quiet)
    assert [r.failure for r in results] == [None] * len(configs)
    assert ok


@pytest.mark.gpu
def test_vectors_decode_identically_with_cuda_initialised():
    configs = [Config(1, "cuda"), Config(2, "cuda")]
    ok, results = check(VECTORS_DIR, configs, echo=_quiet)
    assert [r.failure for r in results] == [None, None]
    assert results[0].environment["cuda_device"]
    assert ok
