"""Real spherical harmonics and the 3DGS color rule (csgs_codec.render.sh)."""

from __future__ import annotations

import math

import pytest
import torch

from csgs_codec.errors import InputError
from csgs_codec.render.sh import SH_C0, sh_basis, sh_degree_of_count, sh_to_color


def _fibonacci_sphere(count: int) -> torch.Tensor:
    """[count, 3] float64 near-uniform unit vectors (equal-area quadrature points)."""
    i = torch.arange(count, dtype=torch.float64) + 0.5
    z = 1 - 2 * i / count
    phi = math.pi * (1 + 5 ** 0.5) * i
    r = torch.sqrt(1 - z * z)
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], dim=-1)


def test_sh_basis_is_orthonormal_on_the_sphere():
    dirs = _fibonacci_sphere(200_000)
    basis = sh_basis(dirs, 3)
    gram = basis.T @ basis * (4 * math.pi / dirs.shape[0])
    assert torch.allclose(gram, torch.eye(16, dtype=torch.float64), atol=1e-3)


def test_sh_basis_has_the_standard_first_bands():
    d = torch.tensor([[0.6, 0.0, 0.8]], dtype=torch.float64)
    basis = sh_basis(d, 1)[0]
    c1 = math.sqrt(3 / (4 * math.pi))
    expected = torch.tensor([0.5 / math.sqrt(math.pi), 0.0, c1 * 0.8, -c1 * 0.6],
                            dtype=torch.float64)
    assert torch.allclose(basis, expected)


def test_sh_basis_counts_follow_the_degree():
    d = torch.tensor([[0.0, 0.0, 1.0]])
    assert [sh_basis(d, k).shape[-1] for k in range(4)] == [1, 4, 9, 16]


def test_degree_zero_color_is_half_plus_c0_times_dc():
    sh = torch.tensor([[[1.0, -0.5, 0.25]]])
    color = sh_to_color(sh, torch.tensor([[0.3, -2.0, 5.0]]))
    assert torch.allclose(color, 0.5 + SH_C0 * sh[:, 0], atol=1e-7)


def test_color_is_clamped_at_zero_not_at_one():
    sh = torch.tensor([[[-10.0, 10.0, 0.0]]])
    color = sh_to_color(sh, torch.tensor([[0.0, 0.0, 1.0]]))
    assert color[0, 0] == 0.0
    assert color[0, 1] > 1.0


def test_color_depends_on_view_direction_through_band_one():
    sh = torch.zeros(1, 4, 3)
    sh[0, 2] = 1.0  # the z-linear function: C1 * z
    up = sh_to_color(sh, torch.tensor([[0.0, 0.0, 2.0]]))
    down = sh_to_color(sh, torch.tensor([[0.0, 0.0, -2.0]]))
    assert torch.allclose(up, torch.full((1, 3), 0.5 + 0.4886025119029199))
    assert torch.allclose(down, torch.full((1, 3), 0.5 - 0.4886025119029199))


def test_incomplete_sh_coefficient_count_is_rejected():
    with pytest.raises(InputError):
        sh_degree_of_count(5)
