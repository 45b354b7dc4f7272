"""Direct solve of (I - R K) B = E with scipy: the reference for small scenes.

The steps before the last assemble F (see ``matrix``); the last step factors each
channel's matrix and solves. A matrix denser than ``DENSE_FRACTION`` fills in under sparse
LU anyway, so it is factored dense by LAPACK (scipy.linalg.lu_factor); sparser ones by
SuperLU (scipy.sparse.linalg.splu). The memory a factorisation needs is checked against the
form-factor cache budget before anything is allocated, and the time the solve will take
against ``MAX_SECONDS``, both from a sample of rows before any assembly.

Fill-in rule (conservative): SuperLU's L + U are taken to hold
``min(n^2, 4 nnz sqrt(n))`` non-zeros, nnz the non-zeros of F projected from the sample.
Form-factor matrices are visibility graphs, which fill in like random sparse matrices, not
like meshes: on a subdivided cube with 15 non-zeros a row L + U held 77% of n^2 (768 and
3,072 patches), with 200 a row 98%; the rule gives 100% for both. Factoring costs
about fill^2 / n multiply-adds per channel (n^3 when dense), at ``FLOPS`` (SuperLU measured
5.7e9 to 1.3e10 on 2 cores).
"""
from __future__ import annotations

import time

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import SceneError
from .base import Solver
from .matrix import Assembly, transport

#: Matrices with more non-zeros than this fraction of n^2 are factored dense.
DENSE_FRACTION = 0.05
#: Direct solves estimated to take longer than this (assembly and factoring) are refused.
MAX_SECONDS = 600.0
#: Multiply-adds per second assumed for the LU (a low measured rate: the estimate errs long).
FLOPS = 5e9


def factor_fill(n: int, nnz: int) -> int:
    """Non-zeros expected in L + U of one channel (the rule in the module docstring)."""
    return int(min(float(n) * n, 4.0 * nnz * np.sqrt(n)))


def projected_nnz(rows, n: int) -> int:
    """Non-zeros of all n rows, projected from the rows held (n^2 when none is)."""
    held = list(rows.held.values())
    if not held:
        return n * n
    return int(sum(len(r.indices) for r in held) / len(held) * n)


def _duration(seconds: float) -> str:
    for unit, size in (("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:,.1f} {unit}"
    return f"{seconds:.1f} s"


class DirectSolver(Solver):
    """Assembles F a batch of rows per step, then solves all channels in one step (``_solve``,
    which ``UserSolver`` replaces with the user's function)."""

    name = "direct"

    def __init__(self, scene, rows, **kw):
        super().__init__(scene, rows, **kw)
        n = scene.n
        rows.rows(np.unique(np.linspace(0, n - 1, min(n, 64)).astype(np.int64)))   # a size sample
        nnz = projected_nnz(rows, n)
        dense = nnz > DENSE_FRACTION * n * n
        self._check_time(n, nnz, rows)
        rows.require_all(n, extra_bytes=self._extra_bytes(n, dense, nnz), why=f"the {self.name} solve of")
        self._assembly = Assembly(rows, n)
        self.B = np.zeros((n, 3))
        self.H = np.zeros((n, 3))
        self.K = None
        self._record(self.emitted)

    @staticmethod
    def factor_bytes(n: int) -> int:
        """Bytes a dense factorisation of one channel needs (the worst case)."""
        return 8 * n * n

    def _extra_bytes(self, n: int, dense: bool, nnz: int) -> int:
        return self.factor_bytes(n) if dense else 12 * factor_fill(n, nnz)

    def _estimate(self, n: int, nnz: int, rows) -> tuple[float, str]:
        """(seconds, what they are) for assembling the rows not held yet and factoring."""
        per_row = rows.seconds / max(rows.computed, 1)
        assemble = per_row * (n - len(rows.held))
        fill = factor_fill(n, nnz)
        factor = 3 * fill * (fill / n) / FLOPS
        return assemble + factor, (f"assembling {n:,} form-factor rows {_duration(assemble)}, LU of about "
                                   f"{fill:.2g} non-zeros a channel {_duration(factor)}")

    def _check_time(self, n: int, nnz: int, rows):
        seconds, what = self._estimate(n, nnz, rows)
        if seconds > MAX_SECONDS:
            raise SceneError(
                f"the {self.name} solve of {n:,} patches would take about {_duration(seconds)} ({what}), over "
                f"the limit of {_duration(MAX_SECONDS)}: use an iterative solver (shooting, jacobi or "
                f"gauss_seidel), or fewer patches")

    @property
    def phase(self) -> str:
        if self.K is None:
            return f"assembling form factors: {self._assembly.cursor:,} of {self.scene.n:,} rows"
        return "solving"

    def _advance(self, t0: float):
        F = self._assembly.step()
        if F is None:
            return
        K = transport(F, self.area)
        self._finish(K, self._solve(F, K), t0)

    def _finish(self, K, B: np.ndarray, t0: float):
        """Take B (scaled units) as the answer: the books and the residual of B."""
        self.K, self.B = K, B
        self.H = self.K @ self.B
        self.iterations = 1
        self._residual = self.E + self.rho * self.H - self.B
        self._record((np.abs(self._residual) * self.area[:, None]).sum(axis=0), time.perf_counter() - t0)

    @property
    def done(self) -> bool:
        """Done once solved; ``converged`` says whether the residual of B met the tolerance."""
        return self.K is not None

    def _solve(self, F, K) -> np.ndarray:
        """B (n, 3) in scaled units: LU of I - R_c K per channel, dense above DENSE_FRACTION fill."""
        n = self.scene.n
        E, rho = self.E.astype(np.float64), self.rho.astype(np.float64)
        dense = K.nnz > DENSE_FRACTION * n * n
        if dense and self.factor_bytes(n) > self.rows.budget_bytes:
            raise SceneError(f"the direct solve of {n:,} patches needs {self.factor_bytes(n) / 2**30:.2f} GiB "
                             f"to factor, over the budget of {self.rows.budget_bytes / 2**30:.2f} GiB")
        Kd = K.toarray() if dense else None
        B = np.empty((n, 3))
        for c in range(3):
            if dense:
                M = -rho[:, c, None] * Kd
                M[np.diag_indices(n)] += 1.0
                B[:, c] = la.lu_solve(la.lu_factor(M, overwrite_a=True, check_finite=False), E[:, c])
            else:
                M = (sp.identity(n, format="csc") - sp.diags(rho[:, c]) @ K).tocsc()
                B[:, c] = spla.splu(M).solve(E[:, c])
        return B

    def _books(self):
        escaped, blocked = self._assembly.losses.lost(self.B * self.area[:, None])
        unshot = (self._residual * self.area[:, None]).sum(axis=0) if self.iterations else self.emitted
        return self.B, self.H, escaped, blocked, unshot
