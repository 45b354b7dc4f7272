"""Progressive-refinement shooting (Cohen, Chen, Wallace and Greenberg 1988).

Each step shoots the patch with the most unshot power dB_i A_i (summed over RGB): for every
patch j it sees, dR_j = rho_j dB_i F_ij A_i / A_j (reciprocity, so only row i is needed), and
dR_j joins both B_j and the unshot dB_j. The solve stops when the unshot power falls below
``tol`` times the emitted power (a relative test: the same at any emission scale), after
``max_iterations`` shots, or when the caller stops stepping (cancel: nothing is written).
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from ..errors import Cancelled
from .result import SolveResult

#: Rows computed ahead in one batch when a shooter's row is missing.
PREFETCH = 64


class ShootingSolver:
    """Shooting state that advances in steps, so a modal operator can interleave events.

    ``rows`` is a ``FormFactors`` or ``RowCache``: anything with ``get(i, prefetch)`` and ``seconds``.
    """

    def __init__(self, scene, rows, *, tol: float = 1e-3, max_iterations: int = 10_000):
        scene.validate()
        self.scene, self.rows, self.tol, self.max_iterations = scene, rows, tol, max_iterations
        self.area = scene.areas[:, None]
        self.B = scene.emission.copy()
        self.dB = scene.emission.copy()
        self.H = np.zeros_like(self.B)
        self.emitted = scene.emitted_power()
        self._scale = np.where(self.emitted > 0, self.emitted, 1.0)
        self.escaped = np.zeros(3)
        self.blocked = np.zeros(3)
        self.unshot_power = (self.dB * self.area).sum(axis=1)
        self.history: list[float] = []
        self.iterations = 0
        self.converged = False
        self.seconds = 0.0

    @property
    def residual(self) -> float:
        """Unshot power over emitted power, worst channel."""
        return float(np.max((self.dB * self.area).sum(axis=0) / self._scale))

    @property
    def done(self) -> bool:
        return self.converged or self.iterations >= self.max_iterations

    def step(self, count: int = 1) -> bool:
        """Shoot up to ``count`` patches; True when the solve is finished."""
        t0 = time.perf_counter()
        for _ in range(count):
            if self.done:
                break
            residual = self.residual
            self.history.append(residual)
            if residual <= self.tol:
                self.converged = True
                break
            self._shoot_one()
        self.seconds += time.perf_counter() - t0
        return self.done

    def _shoot_one(self):
        up, area, rho = self.unshot_power, self.area, self.scene.rho
        i = int(np.argmax(up))
        row = self.rows.get(i, prefetch=lambda: np.argpartition(-up, min(PREFETCH, len(up) - 1))[:PREFETCH])
        power = self.dB[i] * area[i, 0]                   # W per channel leaving patch i
        j = row.indices
        irradiance = np.outer(row.values, power) / area[j]
        self.H[j] += irradiance
        dR = rho[j] * irradiance
        self.B[j] += dR
        self.dB[i] = 0.0
        self.dB[j] += dR
        up[i] = 0.0
        up[j] = (self.dB[j] * area[j]).sum(axis=1)
        self.escaped += row.escaped * power
        self.blocked += row.blocked * power
        self.iterations += 1

    def result(self) -> SolveResult:
        area = self.area
        ff = self.rows.seconds
        return SolveResult(
            B=self.B.copy(), irradiance=self.H.copy(), iterations=self.iterations,
            converged=self.converged, residual_history=list(self.history),
            seconds={"form_factors": ff, "solve": max(self.seconds - ff, 0.0)},
            emitted=self.emitted, absorbed=((1.0 - self.scene.rho) * self.H * area).sum(axis=0),
            escaped=self.escaped.copy(), blocked=self.blocked.copy(),
            unshot=(self.dB * area).sum(axis=0))


def shoot(scene, rows, *, tol: float = 1e-3, max_iterations: int = 10_000,
          progress: Callable[[int, float], bool | None] | None = None) -> SolveResult:
    """Solve ``scene`` by shooting to completion.

    ``progress(iteration, residual)`` is called every 16 shots; returning False cancels
    (raises Cancelled).
    """
    solver = ShootingSolver(scene, rows, tol=tol, max_iterations=max_iterations)
    while not solver.step(16):
        if progress is not None and progress(solver.iterations, solver.residual) is False:
            raise Cancelled("solve cancelled; nothing was changed")
    return solver.result()
