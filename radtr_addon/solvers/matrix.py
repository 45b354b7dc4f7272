"""The form factors as one sparse matrix, assembled a batch of rows per step.

Gathering and the direct solve need every row; they fetch them through ``Assembly`` in
batches (so a modal operator stays responsive and can cancel), noting each row's
losses (escaped, blocked) and F_ii as they pass.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

#: Rows fetched from the form-factor cache per step.
BATCH = 256


class RowLosses:
    """Per-patch escaped and blocked fractions and F_ii, filled as rows pass by."""

    def __init__(self, n: int):
        self.escaped = np.zeros(n)
        self.blocked = np.zeros(n)
        self.self_ff = np.zeros(n)

    def lost(self, out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(escaped, blocked) power per channel of patches sending ``out`` (n, 3) W."""
        return (out * self.escaped[:, None]).sum(axis=0), (out * self.blocked[:, None]).sum(axis=0)

    def note(self, ids, rows):
        for j, r in zip(ids, rows):
            self.escaped[j], self.blocked[j] = r.escaped, r.blocked
            hit = np.searchsorted(r.indices, j)
            if hit < len(r.indices) and r.indices[hit] == j:
                self.self_ff[j] = r.values[hit]


class Assembly:
    """All n rows of ``rows`` into a CSR matrix F, one batch per ``step``."""

    def __init__(self, rows, n: int, dtype=np.float64):
        self.rows, self.n, self.dtype = rows, n, dtype
        self.cursor = 0
        self.losses = RowLosses(n)
        self._parts: list = []

    def step(self) -> sp.csr_matrix | None:
        """Fetch the next batch; the matrix once the last row is in, else None."""
        ids = np.arange(self.cursor, min(self.cursor + BATCH, self.n))
        batch = self.rows.rows(ids)
        self.losses.note(ids, batch)
        self._parts += batch
        self.cursor = int(ids[-1]) + 1
        if self.cursor < self.n:
            return None
        counts = np.array([len(r.indices) for r in self._parts])
        indptr = np.concatenate([[0], np.cumsum(counts)])
        indices = np.concatenate([r.indices for r in self._parts] + [np.zeros(0, np.int64)])
        values = np.concatenate([r.values for r in self._parts] + [np.zeros(0)])
        self._parts = []
        return sp.csr_matrix((values.astype(self.dtype), indices, indptr), shape=(self.n, self.n))


def transport(F: sp.csr_matrix, area: np.ndarray) -> sp.csr_matrix:
    """K = diag(1/A) F^T diag(A): K_ij = F_ji A_j / A_i, the light patch i gathers."""
    return (sp.diags(1.0 / area) @ F.T @ sp.diags(area)).tocsr()
