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
    """U (n, k), V (n, k) sparse and an LU of I_k - V^T R_c U per channel (one in mono).

    ``level`` is the hierarchy level of the clusters, or -1 for a cut mixing levels.
    """

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


def build(hierarchy, rows, level: int, *, dtype=np.float64, budget_bytes: int = 4 << 30,
          progress=None) -> LowRank:
    """Factors of ``hierarchy`` with the nodes of ``level`` as clusters, from ``rows`` (a
    FormFactors of its leaves). Refuses before allocating when they need more than
    ``budget_bytes``, naming the finest level that fits. ``progress(done, total)`` after each
    batch of representative rows."""
    leaves = hierarchy.leaves
    if not 0 <= level <= hierarchy.levels:
        raise SceneError(f"low-rank level must be 0..{hierarchy.levels}, got {level}")
    ks = [len(r) for r in hierarchy.representative]
    need = level_bytes(leaves.n, ks[level], dtype)
    if need > budget_bytes:
        fits = [lv for lv in range(hierarchy.levels + 1) if level_bytes(leaves.n, ks[lv], dtype) <= budget_bytes]
        hint = (f"level {max(fits)} ({ks[max(fits)]:,} clusters) would fit" if fits
                else "no level fits: use fewer patches")
        raise SceneError(f"low-rank factors of level {level} ({ks[level]:,} clusters x {leaves.n:,} patches) need "
                         f"{need / 2**30:.2f} GiB, over the budget of {budget_bytes / 2**30:.2f} GiB; {hint}")
    cut = [(level, g) for g in range(ks[level])]
    lr = build_cut(hierarchy, rows, cut, dtype=dtype, budget_bytes=budget_bytes, progress=progress)
    lr.level = level
    return lr


def build_cut(hierarchy, rows, cut, *, dtype=np.float64, budget_bytes: int = 4 << 30,
              progress=None) -> LowRank:
    """Factors whose clusters are the hierarchy nodes ``cut`` [(level, node), ...], which must
    cover every leaf exactly once (nodes of one level, or of several: see ``refined_cut``)."""
    leaves = hierarchy.leaves
    leaves.validate()
    n, k = leaves.n, len(cut)
    need = level_bytes(n, k, dtype)
    if need > budget_bytes:
        raise SceneError(f"low-rank factors of {k:,} clusters x {n:,} patches need {need / 2**30:.2f} GiB, "
                         f"over the budget of {budget_bytes / 2**30:.2f} GiB")
    t0 = time.perf_counter()
    column = np.full(n, -1, dtype=np.int64)
    rep = np.empty(k, dtype=np.int64)
    for col, (lv, g) in enumerate(cut):
        rep[col] = hierarchy.representative[lv][g]
    for lv in sorted({lv for lv, _ in cut}):
        cols = np.array([c for c, (l2, _) in enumerate(cut) if l2 == lv])
        lookup = np.full(len(hierarchy.representative[lv]), -1, dtype=np.int64)
        lookup[[cut[c][1] for c in cols]] = cols
        hit = lookup[hierarchy.cluster[lv]]
        if np.any((hit >= 0) & (column >= 0)):
            raise SceneError("low-rank cut covers some patches twice")
        column = np.where(hit >= 0, hit, column)
    if np.any(column < 0):
        raise SceneError(f"low-rank cut leaves {int((column < 0).sum())} patches uncovered")
    area = leaves.areas
    V = sp.csr_matrix((area / area[rep[column]], (np.arange(n), column)), shape=(n, k))
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
    return LowRank(U.astype(dtype, copy=False), V, rho, lus, -1, seconds)


def children(hierarchy, level: int) -> dict[int, np.ndarray]:
    """Node g of ``level`` -> its nodes at level + 1."""
    pairs = np.unique(np.stack([hierarchy.cluster[level], hierarchy.cluster[level + 1]], axis=1), axis=0)
    split = np.flatnonzero(np.diff(pairs[:, 0])) + 1
    return {int(grp[0, 0]): grp[:, 1] for grp in np.split(pairs, split)}


def refined_cut(hierarchy, rows, start_level: int, clusters: int, emission=None) -> list[tuple[int, int]]:
    """A cut mixing levels: the nodes of ``start_level``, then, until there are ``clusters``,
    the node carrying the most light (power A B of a solve with the cut so far) replaced by
    its children. Light is refined where it is, the dark rest stays coarse."""
    leaves = hierarchy.leaves
    E = leaves.emission if emission is None else emission
    kids = [children(hierarchy, lv) for lv in range(hierarchy.levels)]
    cut = [(start_level, g) for g in range(len(hierarchy.representative[start_level]))]
    while len(cut) < clusters:
        B = build_cut(hierarchy, rows, cut).solve(E)
        power = leaves.areas * B.sum(axis=1)
        weight = []
        for lv, g in cut:
            weight.append(power[hierarchy.cluster[lv] == g].sum() if lv < hierarchy.levels else -1.0)
        order = np.argsort(weight)[::-1]
        grow = max(1, (clusters - len(cut)) // 4)          # a quarter of what is left per round
        chosen = {int(c) for c in order[:grow] if weight[c] > 0}
        if not chosen:
            break
        new = []
        for c, (lv, g) in enumerate(cut):
            new += [(lv + 1, int(h)) for h in kids[lv][g]] if c in chosen else [(lv, g)]
        cut = new
    return cut
