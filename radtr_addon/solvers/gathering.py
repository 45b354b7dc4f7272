"""Gathering: Jacobi and Gauss-Seidel sweeps of B = E + R K B (see ``base``), from B = 0.

Rows come from the form-factor cache. When all of them are expected to fit in its budget
(``RowCache.projected_bytes``, counting the matrices built from them), the first steps assemble K
as one sparse matrix: a Jacobi sweep is one product K B, a Gauss-Seidel sweep one sparse
triangular solve per channel, (I - R (K_lower + K_diag)) B' = E + R K_upper B. When they do
not fit, every sweep streams the rows in batches (the cache recomputes those it could not
keep) and both methods scatter them by columns.

Row j of F is column j of K, so streamed Gauss-Seidel runs by columns: with the patches in order,
``lower[i]`` collects K_ij B_j from patches j < i already updated in this sweep and
``upper[i]`` those from j > i, updated in the previous sweep; B_j is updated from both
(its own K_jj term solved for) when its turn comes, then its column is scattered. After the
sweep, lower + upper + K_jj B_j is K B for the new B, so the residual is exact at no cost.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .base import Solver
from .matrix import BATCH, Assembly, RowLosses, transport

#: Matrices held in matrix mode, in units of the rows' size: K, and for Gauss-Seidel its
#: upper part and three lower-triangular systems.
MATRIX_COPIES = 5


class GatheringSolver(Solver):
    """Jacobi (``gauss_seidel=False``) or Gauss-Seidel sweeps; one step = one batch of rows."""

    def __init__(self, scene, rows, *, gauss_seidel: bool = False, **kw):
        super().__init__(scene, rows, **kw)
        self.gauss_seidel = gauss_seidel
        self.name = "gauss_seidel" if gauss_seidel else "jacobi"
        n = scene.n
        self._area = self.area[:, None].astype(self.dtype)
        self.B = np.zeros_like(self.E)
        self.H = np.zeros_like(self.E)          # K B_books
        self.B_books = self.B                   # the B whose outgoing light the books count
        self._residual = self.E.copy()
        self._cursor = 0
        self._lower = np.zeros_like(self.E)     # the sweep in progress: K B (Jacobi) or lower
        self._upper = np.zeros_like(self.E)     # Gauss-Seidel: K_ij B_j for j > i, last sweep
        self._upper_next = np.zeros_like(self.E)
        probe = np.unique(np.linspace(0, n - 1, min(n, 64)).astype(np.int64))
        rows.rows(probe)                        # so the cache can project the size of all rows
        self.K = None
        fits = rows.projected_bytes(n) * MATRIX_COPIES <= rows.budget_bytes
        self._assembly = Assembly(rows, n, self.dtype) if fits else None
        self.losses = self._assembly.losses if self._assembly else RowLosses(n)
        self._record((self.E * self._area).sum(axis=0, dtype=np.float64))

    @property
    def phase(self) -> str:
        if self._assembly is not None:
            return f"assembling form factors: {self._assembly.cursor:,} of {self.scene.n:,} rows"
        return f"{self.name} sweep {self.iterations + 1:,}: {self._cursor:,} of {self.scene.n:,} rows"

    def _advance(self, t0: float):
        n = self.scene.n
        if self._assembly is not None:
            F = self._assembly.step()
            if F is not None:
                self._assembly = None
                self._prepare(F)
            return
        if self.K is not None:
            self._matrix_sweep()
            self._cursor = n
        else:
            ids = np.arange(self._cursor, min(self._cursor + BATCH, n))
            for j, (idx, val) in zip(ids, self._columns(ids)):
                self._column(int(j), idx, val)
            self._cursor = int(ids[-1]) + 1
        if self._cursor == n:
            self._end_sweep(t0)

    def _prepare(self, F):
        self.K = transport(F, self.area).astype(self.dtype)
        if self.gauss_seidel:
            lower = sp.tril(self.K, format="csr")
            self._K_upper = sp.triu(self.K, 1, format="csr")
            eye = sp.identity(self.scene.n, dtype=self.dtype, format="csr")
            self._systems = [(eye - sp.diags(self.rho[:, c]) @ lower).tocsr() for c in range(3)]

    def _matrix_sweep(self):
        if not self.gauss_seidel:
            self._lower = self.K @ self.B
            return
        rhs = self.E + self.rho * (self._K_upper @ self.B)
        for c, system in enumerate(self._systems):
            self.B[:, c] = spla.spsolve_triangular(system, rhs[:, c], lower=True)
        self._lower = self.K @ self.B           # K B for the new B: the books and the residual

    def _columns(self, ids):
        """(indices, values) of rows ``ids`` of F from the cache."""
        rows = self.rows.rows(ids)
        if self.iterations == 0:
            self.losses.note(ids, rows)
        return [(r.indices, r.values) for r in rows]

    def _column(self, j: int, idx, val):
        """Scatter column j of K (row j of F): K_ij B_j = F_ji A_j B_j / A_i."""
        weights = (val * (self.area[j] / self.area[idx])).astype(self.dtype)[:, None]
        if not self.gauss_seidel:
            self._lower[idx] += weights * self.B[j]
            return
        gathered = self._lower[j] + self._upper[j]
        self.B[j] = (self.E[j] + self.rho[j] * gathered) / (1.0 - self.rho[j] * self.losses.self_ff[j])
        out = weights * self.B[j]
        later, earlier = idx > j, idx < j
        self._lower[idx[later]] += out[later]
        self._upper_next[idx[earlier]] += out[earlier]

    def _end_sweep(self, t0: float):
        self.iterations += 1
        if self.gauss_seidel:
            if self.K is None:                   # streamed: K B = lower + upper + K_jj B_j
                self._lower += self._upper_next + self.losses.self_ff[:, None].astype(self.dtype) * self.B
                self._upper, self._upper_next = self._upper_next, np.zeros_like(self.E)
            self.H, self.B_books = self._lower, self.B.copy()
            self._residual = self.E + self.rho * self.H - self.B
        else:
            self.H, self.B_books = self._lower, self.B
            self._residual = self.E + self.rho * self.H - self.B
            self.B = self.B + self._residual
        self._lower = np.zeros_like(self.E)
        self._cursor = 0
        self._record((self._residual * self._area).sum(axis=0, dtype=np.float64), time.perf_counter() - t0)

    def _books(self):
        """Books of the last sweep: the light of ``B_books`` (H = K B_books) and its residual.

        Jacobi reports B after the sweep (= E + rho H) and counts the books on the B the
        sweep started from; the sweep's change is the unshot term.
        """
        escaped, blocked = self.losses.lost(self.B_books * self._area)
        return self.B, self.H, escaped, blocked, (self._residual * self._area).sum(axis=0, dtype=np.float64)
