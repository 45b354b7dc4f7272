"""Progressive-refinement shooting (Cohen, Chen, Wallace and Greenberg 1988).

Each step shoots the patch with the most unshot power dB_i A_i (summed over RGB), taken from
a ``ShooterQueue``: for every patch j it sees, dR_j = rho_j dB_i F_ij A_i / A_j (so only
row i is needed) joins both B_j and the unshot dB_j. The unshot radiosity dB is exactly the
residual E + R K B - B of the common system (see ``base``), so the stop test is the one every
solver uses. The ambient term (same paper) estimates the light still unshot, spread evenly,
for showing partial solutions: ``SolveResult.display``.
"""
from __future__ import annotations

import time

import numpy as np

from .base import Solver
from .queue import ShooterQueue

#: Rows computed ahead in one batch when a shooter's row is missing.
PREFETCH = 64
#: Shots between exact recomputations of the unshot totals (kept incrementally in between).
RESYNC = 1024


class ShootingSolver(Solver):
    """Shooting state that advances one shot per unit; continue a stopped solve with ``resume``."""

    name = "shooting"

    def __init__(self, scene, rows, **kw):
        super().__init__(scene, rows, **kw)
        self.B = self.E.copy()
        self.dB = self.E.copy()
        self.H = np.zeros_like(self.B)
        self.escaped = np.zeros(3)
        self.blocked = np.zeros(3)
        self.shot = np.zeros(3)                 # power shot so far, per channel
        self._area = self.area[:, None].astype(self.dtype)
        self.queue = ShooterQueue((self.dB * self._area).sum(axis=1))
        self._unshot = self._unshot_exact()
        self._record(self._unshot)

    def _unshot_exact(self) -> np.ndarray:
        return (self.dB * self._area).sum(axis=0, dtype=np.float64)

    def _advance(self, t0: float):
        queue, area, dt = self.queue, self._area, self.dtype
        i = queue.pop()
        row = self.rows.get(i, prefetch=lambda: np.argpartition(
            -queue.values, min(PREFETCH, len(queue.values) - 1))[:PREFETCH])
        power = self.dB[i] * area[i, 0]                   # leaving patch i, per channel
        self.dB[i] = 0.0
        j = row.indices
        irradiance = (row.values / self.area[j]).astype(dt)[:, None] * power
        self.H[j] += irradiance
        dR = self.rho[j] * irradiance
        self.B[j] += dR
        self.dB[j] += dR
        gained = dR * area[j]
        queue.raise_to(j, (self.dB[j] * area[j]).sum(axis=1))
        self.escaped += row.escaped * power
        self.blocked += row.blocked * power
        self.shot += power
        self.iterations += 1
        if self.iterations % RESYNC == 0:
            self._unshot = self._unshot_exact()
        else:
            self._unshot = self._unshot - power + gained.sum(axis=0, dtype=np.float64)
        self._record(self._unshot, time.perf_counter() - t0)

    def _books(self):
        return self.B, self.H, self.escaped, self.blocked, self._unshot_exact()

    def _ambient(self) -> np.ndarray:
        """Ambient irradiance: the unshot power landing on average, over all bounces, per area.

        Cohen's term is unshot / area / (1 - mean reflectance), for closed scenes. Here a
        fraction ``stay`` of what is shot lands on a front face (1 - (escaped + blocked) / shot,
        measured on the shots so far; 1 before any), so the light still to land is
        unshot x stay / (1 - mean reflectance x stay): Cohen's term when nothing escapes.
        """
        total = self.area.sum()
        mean_rho = (self.scene.rho * self.area[:, None]).sum(axis=0) / total
        lost = (self.escaped + self.blocked) / np.where(self.shot > 0, self.shot, 1.0)
        stay = np.where(self.shot > 0, 1.0 - lost, 1.0)
        return self._unshot_exact() * stay / total / np.maximum(1.0 - mean_rho * stay, 1e-6)

