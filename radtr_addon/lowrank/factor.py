"""Build the low-rank factors of one hierarchy level (see the package docstring)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from ..errors import SceneError


@dataclass
class LowRank:
    """U (n, k), V (n, k) sparse and an LU of I_k - V^T R_c U per channel (one in mono)."""

    U: np.ndarray
    V: sp.csr_matrix
    rho: np.ndarray                         # (n, 3), or (n, 1) in mono
    lu: list                                # per channel (lu, piv) of scipy.linalg.lu_factor
    level: int
    seconds: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.U.shape[0]

    @property
    def k(self) -> int:
        return self.U.shape[1]

    @property
    def channels(self) -> int:
        return len(self.lu)

    def coefficients(self, E: np.ndarray) -> np.ndarray:
        """Z (k, channels) = M_c^-1 V^T E_c: the small per-frame part."""
        W = self.V.T @ E
        return np.stack([la.lu_solve(self.lu[c], W[:, c], check_finite=False)
                         for c in range(self.channels)], axis=1)

    def solve(self, E: np.ndarray) -> np.ndarray:
        """B (n, channels) for emission E (n, channels), numpy float64 reference."""
        return E + self.rho * (self.U @ self.coefficients(E))

    def monochrome(self) -> "LowRank":
        """The same factors for grey light: mean reflectance, one LU (U and V shared)."""
        rho = self.rho.mean(axis=1, keepdims=True)
        M = -(self.V.T @ (rho * self.U))
        M[np.diag_indices(self.k)] += 1.0
        return LowRank(self.U, self.V, rho, [la.lu_factor(M, overwrite_a=True, check_finite=False)], self.level)


def level_bytes(n: int, k: int, dtype=np.float64) -> int:
    """Bytes the factors of a level with k clusters need: U, a float64 work copy, V, the LUs."""
    return n * k * (np.dtype(dtype).itemsize + 8) + 16 * n + 3 * 8 * k * k


def build(hierarchy, rows, level: int, *, dtype=np.float64,
          budget_bytes: int = 4 << 30, progress=None) -> LowRank:
    """Factors of ``hierarchy`` at ``level`` from ``rows`` (a FormFactors of its leaves).

    Refuses before allocating when they need more than ``budget_bytes``, naming the finest
    level that fits. ``progress(done, total)`` after each batch of representative rows.
    """
    leaves = hierarchy.leaves
    leaves.validate()
    n = leaves.n
    if not 0 <= level <= hierarchy.levels:
        raise SceneError(f"low-rank level must be 0..{hierarchy.levels}, got {level}")
    ks = [len(r) for r in hierarchy.representative]
    need = level_bytes(n, ks[level], dtype)
    if need > budget_bytes:
        fits = [lv for lv in range(hierarchy.levels + 1) if level_bytes(n, ks[lv], dtype) <= budget_bytes]
        hint = (f"level {max(fits)} ({ks[max(fits)]:,} clusters) would fit" if fits
                else "no level fits: use fewer patches")
        raise SceneError(f"low-rank factors of level {level} ({ks[level]:,} clusters x {n:,} patches) need "
                         f"{need / 2**30:.2f} GiB, over the budget of {budget_bytes / 2**30:.2f} GiB; {hint}")
    t0 = time.perf_counter()
    cluster, rep = hierarchy.cluster[level], hierarchy.representative[level]
    k = len(rep)
    area = leaves.areas
    V = sp.csr_matrix((area / area[rep[cluster]], (np.arange(n), cluster)), shape=(n, k))
    U = np.zeros((n, k))
    seconds = {"V": time.perf_counter() - t0}
    t0 = time.perf_counter()
    ff0 = rows.seconds
    batch = 256
    for start in range(0, k, batch):
        ids = rep[start:start + batch]
        for g, row in zip(range(start, start + len(ids)), rows.rows(ids)):
            U[row.indices, g] = area[rep[g]] * row.values / area[row.indices]
        if progress is not None:
            progress(min(start + batch, k), k)
    seconds["form_factors"] = rows.seconds - ff0
    seconds["U"] = time.perf_counter() - t0 - seconds["form_factors"]
    t0 = time.perf_counter()
    rho = leaves.rho
    lus = []
    for c in range(rho.shape[1]):
        M = -(V.T @ (rho[:, c, None] * U))
        M[np.diag_indices(k)] += 1.0
        lus.append(la.lu_factor(M, overwrite_a=True, check_finite=False))
    seconds["factor"] = time.perf_counter() - t0
    return LowRank(U.astype(dtype, copy=False), V, rho, lus, level, seconds)
