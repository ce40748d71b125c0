"""Third-degree spherical-radial cubature rule (seed A, eqs. A.7-A.8, A.12-A.13) and moments.

Every function broadcasts over leading batch axes: ``x`` is (..., n), ``P``
is (..., n, n), cubature points are (..., 2n, n). Covariances are computed as
centred sums ``Σ w (Y - ȳ)(Y - ȳ)ᵀ``; the raw second moments printed in A.11,
A.16 and A.17 lose about 13 digits when the state is in radians (docs/design.md
section 8).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

_JITTER_REL: float = 1e-12
"""Jitter added to a non positive-definite matrix, relative to its mean diagonal."""
_TINY: float = 1e-300


def symmetrize(p: np.ndarray) -> np.ndarray:
    """(P + Pᵀ) / 2 over the last two axes."""
    return 0.5 * (p + np.swapaxes(p, -1, -2))


def robust_cholesky(p: np.ndarray) -> np.ndarray:
    """A square root S with S Sᵀ = P (A.7, A.12) that never raises and never returns NaN.

    Tries the plain Cholesky factor of the symmetrized matrix; when that fails
    (nearly singular or slightly indefinite after rounding), projects P onto
    the positive semi-definite cone (eigenvalues clamped at a jitter relative
    to its scale) and returns Q sqrt(Λ), a valid but non-triangular square root.
    Non-finite entries are replaced by zero before the projection.
    """
    p = symmetrize(np.asarray(p, dtype=float))
    try:
        s = np.linalg.cholesky(p)
        if np.all(np.isfinite(s)):
            return s
    except np.linalg.LinAlgError:
        pass
    p = np.where(np.isfinite(p), p, 0.0)
    w, q = np.linalg.eigh(p)
    n = p.shape[-1]
    scale = np.abs(np.trace(p, axis1=-2, axis2=-1))[..., None] / n
    w = np.maximum(w, _JITTER_REL * scale + _TINY)
    return q * np.sqrt(w)[..., None, :]


def cholesky_2x2(p: np.ndarray) -> np.ndarray:
    """Closed-form lower Cholesky factor of 2x2 matrices (..., 2, 2); clamps instead of failing."""
    p11 = p[..., 0, 0]
    p22 = p[..., 1, 1]
    p12 = 0.5 * (p[..., 0, 1] + p[..., 1, 0])
    floor = _JITTER_REL * np.abs(p11 + p22) + _TINY
    l11 = np.sqrt(np.maximum(p11, floor))
    l21 = p12 / l11
    l22 = np.sqrt(np.maximum(p22 - l21 * l21, floor))
    s = np.zeros(p.shape, dtype=float)
    s[..., 0, 0] = l11
    s[..., 1, 0] = l21
    s[..., 1, 1] = l22
    return s


def unit_points(n: int) -> np.ndarray:
    """The 2n cubature directions ξ_i = ±sqrt(n) e_i (A.8), shape (2n, n): +e_1..+e_n, -e_1..-e_n."""
    eye = np.sqrt(n) * np.eye(n)
    return np.concatenate([eye, -eye], axis=0)


def cubature_points(x: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points X_i = S ξ_i + x̂ (A.8, A.13) for means (..., n) and square roots (..., n, n)."""
    n = x.shape[-1]
    xi = unit_points(n)                                  # (2n, n)
    offsets = np.einsum("...jk,ik->...ij", s, xi)         # (..., 2n, n)
    return x[..., None, :] + offsets


def weighted_mean_cov(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equal-weight mean (A.10, A.15) and centred covariance of points (..., 2n, m)."""
    mean = y.mean(axis=-2)
    d = y - mean[..., None, :]
    cov = np.einsum("...ij,...ik->...jk", d, d) / y.shape[-2]
    return mean, cov


def cross_covariance(x_pts: np.ndarray, x_mean: np.ndarray, z_pts: np.ndarray, z_mean: np.ndarray) -> np.ndarray:
    """Centred cross-covariance Σ w (X_i - x̂)(Z_i - ẑ)ᵀ (A.17), shape (..., n, m)."""
    dx = x_pts - x_mean[..., None, :]
    dz = z_pts - z_mean[..., None, :]
    return np.einsum("...ij,...ik->...jk", dx, dz) / x_pts.shape[-2]


def cubature_transform(
    x: np.ndarray, p: np.ndarray, fn: Callable[[np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Propagate N(x, P) through fn with the cubature rule: (mean, cov, cross-cov, points).

    ``fn`` maps points (..., 2n, n) to (..., 2n, m). The cross-covariance is
    between the input points and their images (A.17).
    """
    pts = cubature_points(x, robust_cholesky(p))
    y = fn(pts)
    mean, cov = weighted_mean_cov(y)
    return mean, cov, cross_covariance(pts, x, y, mean), pts
