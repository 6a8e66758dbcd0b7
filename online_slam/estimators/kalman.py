"""Pieces of a Kalman update that touches few columns, shared by the EKF and the smoother's marginal prior."""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import blas

Array = NDArray[np.float64]

SYRK_MIN = 64
"""Below this size :func:`downdate` uses numpy (``W @ W.T``: syrk, then mirrored; the temporary is small)."""

MIRROR_BLOCK = 128
"""Rows per block of :func:`mirror_upper` (a transposed copy of a block stays in cache)."""


def mirror_upper(F: Array) -> None:
    """Copy the upper triangle of square F onto its lower one, in place: F is then symmetric bit for bit.

    BLAS kernels that update both triangles (``ger``, two ``syrk``) round each entry on its own, and whether
    ``F[i, j]`` equals ``F[j, i]`` then depends on the kernel the CPU selects. Computing one triangle and mirroring
    it is symmetric by construction on every CPU. Blocks of :data:`MIRROR_BLOCK` rows keep the copy O(n^2) without
    an n x n temporary.
    """
    n = len(F)
    for i in range(0, n, MIRROR_BLOCK):
        j = min(i + MIRROR_BLOCK, n)
        F[j:, i:j] = F[i:j, j:].T
        block = F[i:j, i:j]
        upper = _upper(j - i)
        block.T[upper] = block[upper]


@functools.cache
def _upper(size: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The strict upper triangle's indices of a (size, size) block (computed once per size: every update uses them)."""
    return np.triu_indices(size, 1)


def stacked_jacobian(J_pose: Array, J_landmark: Array, pose_first: bool = True) -> Array:
    """The compact Jacobian of k range-bearing observations over [pose, landmark 1..k] (or [landmarks.., pose]).

    Args:
        J_pose: d z_i / d pose, shape (k, 2, 3).
        J_landmark: d z_i / d landmark_i, shape (k, 2, 2).
        pose_first: Pose columns first (else last).

    Returns:
        Shape (2k, 3 + 2k); observation i's landmark occupies its own two columns.
    """
    k = len(J_pose)
    H = np.zeros((2 * k, 3 + 2 * k))
    pose, first = (slice(0, 3), 3) if pose_first else (slice(2 * k, 2 * k + 3), 0)
    H[:, pose] = J_pose.reshape(2 * k, 3)
    rows = np.arange(2 * k)[:, None]
    H[rows, first + 2 * (rows // 2) + np.arange(2)] = J_landmark.reshape(2 * k, 2)
    return H


def downdate(cov: Array, W: Array) -> None:
    """``cov -= W W^T`` in place, without an n x n temporary when cov is contiguous, symmetric bit for bit.

    Memory traffic, not arithmetic, is the cost of a low-rank update of a large covariance: numpy's
    ``cov -= W @ W.T`` writes the product to a temporary and reads it back; an in-place BLAS syrk on one
    triangle, mirrored (:func:`mirror_upper`), does not.

    Args:
        cov: Symmetric matrix, shape (n, n), C- or Fortran-contiguous for the fast path; updated in place.
        W: Shape (n, m).
    """
    F = cov.T if cov.flags.c_contiguous else cov  # the Fortran-ordered view BLAS updates in place
    if len(cov) < SYRK_MIN or not F.flags.f_contiguous or cov.dtype != np.float64:
        cov -= W @ W.T  # numpy: syrk, then mirrored
        return
    Wf = np.asfortranarray(W, dtype=np.float64)
    upper = blas.dsyrk(-1.0, Wf, beta=1.0, c=F, overwrite_c=1, lower=0)
    assert np.shares_memory(upper, cov), "syrk did not update in place"
    mirror_upper(F)


def apply_update(
    cov: Array, PHt: Array, S: Array, y: Array, exactly_symmetric: bool = True
) -> tuple[Array, Array, Array]:
    """``cov -= K S K^T`` in place with ``K = P H^T S^-1``, through the Cholesky factor of S.

    Args:
        cov: Covariance, shape (n, n); updated in place.
        PHt: ``P H^T``, shape (n, m).
        S: Innovation covariance, shape (m, m).
        y: Innovation, shape (m,).
        exactly_symmetric: True: numpy's ``W @ W.T`` (syrk, then mirrored); False: :func:`downdate` (syrk in
            place, then mirrored: no n x n temporary, faster on large contiguous cov). Both keep cov symmetric
            bit for bit.

    Returns:
        (state correction K y (n,), W = P H^T L^-T (n, m), L^-1 (m, m)) with ``S = L L^T``.
    """
    L_inv = np.linalg.inv(np.linalg.cholesky(S))  # S is small (m x m); raises LinAlgError, cov untouched
    W = PHt @ L_inv.T
    if exactly_symmetric:
        cov -= W @ W.T
    else:
        downdate(cov, W)
    return W @ (L_inv @ y), W, L_inv
