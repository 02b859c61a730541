"""Real spherical harmonics of degree 0..3 and the 3DGS view-dependent color.

The basis order and constants are the ones every 3DGS trainer uses (INRIA layout): index 0 is
the DC term, then band 1 (3 functions), band 2 (5) and band 3 (7), each band ordered m = -l..l
with the Condon-Shortley sign folded into the constants. The color of a Gaussian seen along the
unit direction d (from the camera centre to the Gaussian) is ``max(0, 0.5 + sum_k c_k Y_k(d))``.
"""

from __future__ import annotations

import torch

from csgs_codec.errors import InputError

#: Y_0^0 normalisation, 1 / (2 sqrt(pi)).
SH_C0 = 0.28209479177387814
#: Band-1 normalisation, sqrt(3 / (4 pi)).
SH_C1 = 0.4886025119029199
#: Band-2 constants in basis order.
SH_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
         0.5462742152960396)
#: Band-3 constants in basis order.
SH_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
         -0.4570457994644658, 1.445305721320277, -0.5900435899266435)

#: Number of basis functions (DC included) for SH degree 0..3.
SH_BASIS_COUNTS = {0: 1, 1: 4, 2: 9, 3: 16}


def sh_degree_of_count(count: int) -> int:
    """SH degree (0..3) whose basis has ``count`` functions (1, 4, 9 or 16)."""
    for degree, n in SH_BASIS_COUNTS.items():
        if n == count:
            return degree
    raise InputError(f"{count} SH coefficients is not a full basis of degree 0..3",
                     property="sh")


def sh_basis(directions: torch.Tensor, degree: int) -> torch.Tensor:
    """Evaluate the real SH basis up to ``degree`` at unit directions.

    Args:
        directions: [..., 3] unit vectors (x, y, z), any float dtype.
        degree: 0..3.

    Returns:
        [..., (degree + 1) ** 2] basis values, same dtype as ``directions``.
    """
    x, y, z = directions.unbind(-1)
    out = [torch.full_like(x, SH_C0)]
    if degree >= 1:
        out += [-SH_C1 * y, SH_C1 * z, -SH_C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        out += [
            SH_C2[0] * x * y,
            SH_C2[1] * y * z,
            SH_C2[2] * (2.0 * zz - xx - yy),
            SH_C2[3] * x * z,
            SH_C2[4] * (xx - yy),
        ]
    if degree >= 3:
        out += [
            SH_C3[0] * y * (3.0 * xx - yy),
            SH_C3[1] * x * y * z,
            SH_C3[2] * y * (4.0 * zz - xx - yy),
            SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            SH_C3[4] * x * (4.0 * zz - xx - yy),
            SH_C3[5] * z * (xx - yy),
            SH_C3[6] * x * (xx - 3.0 * yy),
        ]
    return torch.stack(out, dim=-1)


def sh_to_color(sh: torch.Tensor, directions: torch.Tensor) -> torch.Tensor:
    """View-dependent RGB of Gaussians from their SH coefficients.

    Args:
        sh: [N, K, 3] coefficients, K = (degree + 1) ** 2 in {1, 4, 9, 16}, DC first, then
            the rest coefficient-major (as ``cat([sh_dc[:, None], sh_rest], dim=1)``).
        directions: [N, 3] viewing directions from the camera centre to each Gaussian; they
            are normalised here (a zero vector gives the DC color only).

    Returns:
        [N, 3] color ``max(0, 0.5 + sum_k sh[:, k] * Y_k(d))``, linear, unbounded above.
    """
    degree = sh_degree_of_count(int(sh.shape[-2]))
    norm = torch.linalg.vector_norm(directions, dim=-1, keepdim=True)
    unit = directions / torch.clamp(norm, min=1e-12)
    basis = sh_basis(unit, degree)
    return torch.clamp(0.5 + torch.einsum("nk,nkc->nc", basis, sh), min=0.0)
