"""PlainAdam follows torch's Adam and never imports torch._dynamo."""

from __future__ import annotations

import subprocess
import sys

import torch

from csgs_codec.train.plain_adam import PlainAdam


def test_plain_adam_follows_torch_adam():
    start = torch.randn(6, 4, generator=torch.Generator().manual_seed(0))
    ours, theirs = start.clone().requires_grad_(True), start.clone().requires_grad_(True)
    plain, reference = PlainAdam([ours], lr=0.05), torch.optim.Adam([theirs], lr=0.05)
    for _ in range(30):
        for optimizer, value in ((plain, ours), (reference, theirs)):
            optimizer.zero_grad()
            (value ** 3 - 2 * value).sum().backward()
            optimizer.step()
    assert not torch.equal(ours, start)
    torch.testing.assert_close(ours, theirs, rtol=1e-5, atol=1e-6)


def test_the_semantic_stage_does_not_import_dynamo():
    code = ("import sys\n"
            "from csgs_codec.train.semantic_stage import prepare_semantic_views, "
            "train_semantic_features\n"
            "from csgs_codec.train.synthetic import make_synthetic_dataset\n"
            "d = make_synthetic_dataset(1, objects=2, gaussians_per_object=20, views=2, "
            "width=16, height=12)\n"
            "train_semantic_features(prepare_semantic_views(d.scene, d.views), len(d.scene), "
            "iterations=2)\n"
            "print('torch._dynamo' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, check=True)
    assert done.stdout.strip().splitlines()[-1] == "False"
