"""Radiosity solvers over form-factor rows, all solving the same system (see ``base``).

``make_solver(method, scene, rows, ...)`` builds one by name; ``solve`` runs it to the end.
Every solver steps (``step``), so a modal operator can interleave events, and returns a
``SolveResult`` with the same books.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import Cancelled, SettingsError
from .base import Solver, check_energy_decays
from .direct import DirectSolver
from .gathering import GatheringSolver
from .result import SolveResult
from .shooting import ShootingSolver

#: Solver names, as the CLI, the Scene settings and the benchmarks spell them ("user": ``user``).
SOLVERS = ("shooting", "jacobi", "gauss_seidel", "direct")
#: Every solver a solve can name: these, your own function, and adaptive links (``hierarchical``).
ALL_SOLVERS = (*SOLVERS, "user", "hierarchical")

#: Peak bytes per patch from subdivision to the first solver steps, form-factor rows kept in
#: the cache and a direct solve's factors excluded (each checked against the budget on its
#: own). Measured on 786,432 patches with Embree rows: shooting 1,437 (tracemalloc; Embree's
#: own scene besides), gathering 4,583 (a batch of rows in flight); rounded up.
PATCH_BYTES = {"shooting": 2048, "jacobi": 5120, "gauss_seidel": 5120, "direct": 5120, "user": 5120}


def patch_bytes(method: str) -> int:
    """Bytes a patch costs the ``method`` solve (see ``PATCH_BYTES``); the most for unknown names."""
    return PATCH_BYTES.get(method, max(PATCH_BYTES.values()))


def make_solver(method: str, scene, rows, *, tol: float = 1e-3, max_iterations: int = 10_000,
                dtype=np.float64, user: str = "") -> Solver:
    kw = dict(tol=tol, max_iterations=max_iterations, dtype=dtype)
    if method == "user":
        from .user import UserSolver

        return UserSolver(scene, rows, spec=user, **kw)
    if method == "shooting":
        return ShootingSolver(scene, rows, **kw)
    if method in ("jacobi", "gauss_seidel"):
        return GatheringSolver(scene, rows, gauss_seidel=method == "gauss_seidel", **kw)
    if method == "direct":
        return DirectSolver(scene, rows, **kw)
    raise SettingsError(f"solver must be one of {', '.join(SOLVERS)} or user, got '{method}'")


def solve(method: str, scene, rows, *, progress: Callable[[Solver], bool | None] | None = None,
          **kw) -> SolveResult:
    """Run solver ``method`` to the end; ``progress(solver)`` may return False to cancel."""
    solver = make_solver(method, scene, rows, **kw)
    while not solver.step(16):
        if progress is not None and progress(solver) is False:
            raise Cancelled("solve cancelled; nothing was changed")
    return solver.result()


__all__ = ["PATCH_BYTES", "SOLVERS", "SolveResult", "Solver", "ShootingSolver", "GatheringSolver", "DirectSolver",
           "check_energy_decays", "make_solver", "patch_bytes", "solve"]
