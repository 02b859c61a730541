"""From 3D Gaussians to screen-space ellipses: covariance, EWA projection and culling.

Conventions: the camera is OpenCV-style (x right, y down, z forward); a point at camera-space
(x, y, z) lands on pixel coordinates (fx x / z + cx, fy y / z + cy), where the centre of pixel
column u, row v sits at (u + 0.5, v + 0.5). Every function here is differentiable torch and
follows the dtype of its inputs (float32 for rendering, float64 for gradient checks).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch

from csgs_codec.scene.camera import DEFAULT_NEAR_PLANE, Camera

#: Variance in pixels^2 added to every projected covariance (the 3DGS anti-aliasing low-pass).
LOW_PASS_VARIANCE = 0.3
#: A Gaussian contributes to a pixel only where its alpha reaches this value.
ALPHA_THRESHOLD = 1.0 / 255.0
#: The perspective Jacobian is evaluated at the centre clamped to this multiple of the field of
#: view, so Gaussians far outside the image do not get huge footprints (as in the INRIA code).
JACOBIAN_FOV_MARGIN = 1.3


class ProjectedGaussians(NamedTuple):
    """Screen-space Gaussians, one row per input Gaussian (culled rows keep finite values).

    Attributes:
        means2d: [N, 2] centre in pixel coordinates (x, y).
        conics: [N, 3] inverse 2D covariance (a, b, c): d^T S^-1 d = a dx^2 + 2 b dx dy + c dy^2.
        depths: [N] camera-space z of the centre (world units).
        opacities: [N] sigmoid of the opacity logits, in (0, 1).
        extents: [N, 2] half width and half height in pixels of the box outside which the
            Gaussian's alpha is below :data:`ALPHA_THRESHOLD` (an exact bound, plus a hair).
        visible: [N] bool, False for Gaussians culled by the near plane, the frustum, a
            degenerate footprint or an opacity that can never reach the threshold.
    """

    means2d: torch.Tensor
    conics: torch.Tensor
    depths: torch.Tensor
    opacities: torch.Tensor
    extents: torch.Tensor
    visible: torch.Tensor


def quaternion_to_rotation(quats: torch.Tensor) -> torch.Tensor:
    """Rotation matrices from quaternions (w, x, y, z), normalised here.

    Args:
        quats: [N, 4] quaternions of any length; a zero quaternion gives the identity.

    Returns:
        [N, 3, 3] rotation matrices.
    """
    # Divide by the largest component first: the squared norm of a quaternion of length 1e-20
    # or 1e20 under- or overflows float32, which would leave it unnormalised.
    largest = quats.abs().amax(dim=-1, keepdim=True)
    q = quats / torch.where(largest > 0, largest, torch.ones_like(largest))
    q = q / torch.clamp(torch.linalg.vector_norm(q, dim=-1, keepdim=True), min=1e-12)
    w, x, y, z = q.unbind(-1)
    rows = [
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ]
    return torch.stack(rows, dim=-1).reshape(q.shape[:-1] + (3, 3))


def quaternions_from_smallest_three(axis: torch.Tensor, rest: torch.Tensor) -> torch.Tensor:
    """[N, 4] unit quaternions (w, x, y, z) from their coded form, differentiably.

    Args:
        axis: [N] int64 index of the dropped largest component.
        rest: [N, 3] the other three components times sqrt 2, in their order (as
            :func:`csgs_codec.attributes.attribute_forms.quaternion_to_smallest_three` gives them).
    """
    c = rest / math.sqrt(2.0)
    big = torch.sqrt(torch.clamp(1 - (c * c).sum(1), min=1e-12))
    n = rest.shape[0]
    columns = torch.arange(4, device=axis.device)[None, :].expand(n, 4)
    others = columns[columns != axis[:, None]].reshape(n, 3)
    out = torch.zeros((n, 4), dtype=rest.dtype, device=rest.device).scatter(
        1, axis[:, None], big[:, None])
    return out.scatter(1, others, c)


def covariance_3d(log_scales: torch.Tensor, quats: torch.Tensor) -> torch.Tensor:
    """World-space covariance R S S^T R^T of each Gaussian.

    Args:
        log_scales: [N, 3] natural-log standard deviations along the local axes.
        quats: [N, 4] rotations (w, x, y, z), not necessarily normalised.

    Returns:
        [N, 3, 3] symmetric covariance matrices, world units squared.
    """
    rot = quaternion_to_rotation(quats)
    m = rot * torch.exp(log_scales)[..., None, :]
    return m @ m.transpose(-1, -2)


def _footprint_determinant(to_screen: torch.Tensor, rotation: torch.Tensor,
                           log_scales: torch.Tensor, a_bare: torch.Tensor,
                           c_bare: torch.Tensor) -> torch.Tensor:
    """Determinant [N] of the 2D covariance (a_bare + v, b; b, c_bare + v), v the low-pass.

    ``a c - b^2`` cancels catastrophically in float32 for long thin Gaussians (their footprint
    is nearly a line: a c and b^2 agree to many digits), which turns the conic into noise.
    With rows s0, s1 of (J W) M, M = R diag(scale), Lagrange's identity gives
    |s0|^2 |s1|^2 - (s0 . s1)^2 = |s0 x s1|^2, and s0 x s1 = cof(scale) R^T (A0 x A1) with
    A = J W and cof(scale) = (s1 s2, s0 s2, s0 s1): a sum of squares, no cancellation.
    """
    normal = torch.linalg.cross(to_screen[:, 0], to_screen[:, 1], dim=-1)
    local = (rotation.transpose(-1, -2) @ normal[..., None])[..., 0]
    cofactors = torch.exp(log_scales.sum(-1, keepdim=True) - log_scales)
    area = ((cofactors * local) ** 2).sum(-1)
    return area + LOW_PASS_VARIANCE * (a_bare + c_bare) + LOW_PASS_VARIANCE**2


def camera_matrices(camera: Camera, dtype: torch.dtype,
                    device: torch.device | str = "cpu") -> tuple[torch.Tensor, torch.Tensor]:
    """The camera's world-to-camera rotation [3, 3] and translation [3] as tensors."""
    w2c = torch.as_tensor(camera.world_to_camera, dtype=dtype, device=device)
    return w2c[:3, :3], w2c[:3, 3]


def project_gaussians(means: torch.Tensor, log_scales: torch.Tensor, quats: torch.Tensor,
                      opacity_logits: torch.Tensor, camera: Camera, *,
                      near_plane: float = DEFAULT_NEAR_PLANE) -> ProjectedGaussians:
    """EWA-project Gaussians onto the image plane and cull the ones that cannot be seen.

    The 2D covariance is J W S W^T J^T + 0.3 I, with W the camera rotation and J the Jacobian of
    the perspective projection at the Gaussian's centre.

    Args:
        means: [N, 3] world positions.
        log_scales: [N, 3] natural-log scales.
        quats: [N, 4] rotations (w, x, y, z).
        opacity_logits: [N] opacity before the sigmoid.
        camera: pinhole camera (intrinsics in pixels, world_to_camera 4x4).
        near_plane: Gaussians whose camera-space z is not above this are culled.

    Returns:
        :class:`ProjectedGaussians`, differentiable with respect to all inputs.
    """
    rot_w2c, trans_w2c = camera_matrices(camera, means.dtype, means.device)
    p_cam = means @ rot_w2c.T + trans_w2c
    x, y, z = p_cam.unbind(-1)
    in_front = z > near_plane
    # Culled rows get a harmless depth so no NaN or inf can leak into gradients.
    z_safe = torch.where(in_front, z, torch.ones_like(z))
    fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
    means2d = torch.stack([fx * x / z_safe + cx, fy * y / z_safe + cy], dim=-1)

    lim_x_neg = JACOBIAN_FOV_MARGIN * cx / fx
    lim_x_pos = JACOBIAN_FOV_MARGIN * (camera.width - cx) / fx
    lim_y_neg = JACOBIAN_FOV_MARGIN * cy / fy
    lim_y_pos = JACOBIAN_FOV_MARGIN * (camera.height - cy) / fy
    tx = z_safe * torch.clamp(x / z_safe, -lim_x_neg, lim_x_pos)
    ty = z_safe * torch.clamp(y / z_safe, -lim_y_neg, lim_y_pos)
    zero = torch.zeros_like(z_safe)
    jac = torch.stack([
        fx / z_safe, zero, -fx * tx / (z_safe * z_safe),
        zero, fy / z_safe, -fy * ty / (z_safe * z_safe),
    ], dim=-1).reshape(-1, 2, 3)

    # With S = M M^T (M = R diag(scale)), J W S W^T J^T = (J W M)(J W M)^T: one batched
    # [2, 3] x [3, 3] product instead of a chain of 3x3 ones.
    rotation = quaternion_to_rotation(quats)
    to_screen = jac @ rot_w2c
    screen = to_screen @ (rotation * torch.exp(log_scales)[:, None, :])
    a_bare = (screen[:, 0] * screen[:, 0]).sum(-1)
    c_bare = (screen[:, 1] * screen[:, 1]).sum(-1)
    a = a_bare + LOW_PASS_VARIANCE
    b = (screen[:, 0] * screen[:, 1]).sum(-1)
    c = c_bare + LOW_PASS_VARIANCE
    det = _footprint_determinant(to_screen, rotation, log_scales, a_bare, c_bare)
    nondegenerate = det > 0
    det_safe = torch.where(nondegenerate, det, torch.ones_like(det))
    conics = torch.stack([c / det_safe, -b / det_safe, a / det_safe], dim=-1)

    opacities = torch.sigmoid(opacity_logits)
    # alpha >= 1/255 exactly inside d^T S^-1 d <= 2 ln(255 opacity); the box bounding that
    # ellipse has half sides sqrt(k S_xx), sqrt(k S_yy).
    with torch.no_grad():
        k = 2.0 * torch.log(torch.clamp(opacities / ALPHA_THRESHOLD, min=1.0))
        extents = torch.sqrt(torch.clamp(k[:, None] * torch.stack([a, c], dim=-1), min=0.0))
        extents = extents * (1.0 + 1e-4) + 1e-3
        reaches_threshold = opacities > ALPHA_THRESHOLD
        mx, my = means2d[:, 0], means2d[:, 1]
        on_screen = ((mx + extents[:, 0] > 0) & (mx - extents[:, 0] < camera.width)
                     & (my + extents[:, 1] > 0) & (my - extents[:, 1] < camera.height))
        visible = in_front & nondegenerate & reaches_threshold & on_screen
        visible &= torch.isfinite(means2d).all(-1) & torch.isfinite(conics).all(-1)
    return ProjectedGaussians(means2d, conics, z_safe, opacities, extents, visible)

