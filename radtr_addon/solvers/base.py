"""What every solver shares: the system, its scaling, the stop test, the books and the steps.

The system. Row i of the form factors, F_ij, says where the light leaving patch i goes
(with what escapes the scene and what hits back faces, it sums to 1). Every solver solves

    B = E + R K B,   K_ij = F_ji A_j / A_i,

the light reaching patch i being the power other patches send it through their own rows.
This is the system progressive shooting solves; it conserves energy exactly, and because
every solver uses it they agree to their tolerances even where point-sampled form factors
are not reciprocal pair by pair (A_i F_ij != A_j F_ji). With exact form factors K = F.

Scaling. E is divided by its largest value before solving and B multiplied back after, so
emission in any units (1e-30 or 1e+30) gives the same iterations and float32 neither
underflows nor overflows.

Stop test. With the residual r = E + R K B - B, a solve stops when the residual power
sum_i A_i |r_i| is at most ``tol`` x the emitted power (worst channel). The power-weighted
1-norm of R K is at most rho_max, so the power error of B is then at most
tol x emitted / (1 - rho_max): in a white furnace, a relative error of at most ``tol``.
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import SceneError, SettingsError
from .result import SolveResult

#: A row whose escaped + blocked fraction is below this keeps all its light in the scene.
CLOSED_ROW_LOSS = 1e-9


def check_energy_decays(scene, rows):
    """Raise SceneError when light could bounce for ever.

    That happens, per channel, when some set of patches with reflectance 1 sends all of its
    light to patches of the same set (nothing escapes, is blocked or is absorbed): the
    largest such set is found by dropping, until none is left to drop, every patch of
    reflectance 1 whose row loses light or reaches a patch outside the set.
    """
    for c, channel in enumerate("RGB"):
        trapped = scene.rho[:, c] >= 1.0
        if not trapped.any():
            continue
        ids = np.flatnonzero(trapped)
        own = dict(zip(ids.tolist(), rows.rows(ids)))
        changed = True
        while changed:
            changed = False
            for i in np.flatnonzero(trapped):
                r = own[int(i)]
                if r.escaped + r.blocked > CLOSED_ROW_LOSS or not trapped[r.indices].all():
                    trapped[i] = False
                    changed = True
        if trapped.any():
            first = int(np.flatnonzero(trapped)[0])
            raise SceneError(
                f"light would never decay in channel {channel}: {int(trapped.sum())} patches reflect all of "
                f"it and send all of it to one another, e.g. {scene.patch_label(first)}; lower their "
                f"reflectance below 1 or let light escape")


class Solver:
    """Base of the solvers: ``step`` advances one unit of work (a shot, a batch of rows, a sweep).

    ``rows`` is a ``FormFactors`` or any ``RowCache``: ``rows(ids)``, ``get(i, prefetch)``,
    ``seconds`` and a byte budget. A solver can be stopped between steps and continued with
    ``resume``; nothing outside it changes until the caller takes its ``result``.
    """

    name = "?"

    def __init__(self, scene, rows, *, tol: float = 1e-3, max_iterations: int = 10_000, dtype=np.float64):
        if not tol >= 0:
            raise SettingsError(f"tolerance must be 0 or more, got {tol}")
        if max_iterations < 1:
            raise SettingsError(f"iterations must be at least 1, got {max_iterations}")
        if np.dtype(dtype) not in (np.float32, np.float64):
            raise SettingsError(f"precision must be float32 or float64, got {dtype}")
        scene.validate()
        self.scene, self.rows, self.tol, self.max_iterations = scene, rows, tol, max_iterations
        self.dtype = np.dtype(dtype)
        self.area = scene.areas
        self.scale = float(scene.emission.max())
        self.E = (scene.emission / self.scale).astype(self.dtype)
        self.rho = scene.rho.astype(self.dtype)
        self.emitted = (self.E * self.area[:, None]).sum(axis=0, dtype=np.float64)
        self._norm = np.where(self.emitted > 0, self.emitted, 1.0)
        self._rows_seconds = rows.seconds
        self.iterations = 0
        self.converged = False
        self.seconds = 0.0
        self.history: list[float] = []
        self.times: list[float] = []
        if (scene.rho >= 1.0).any():
            check_energy_decays(scene, rows)

    # -- progress ---------------------------------------------------------------------------
    @property
    def residual(self) -> float:
        """Residual power over emitted power, worst channel (1 before any work)."""
        return self.history[-1] if self.history else 1.0

    @property
    def done(self) -> bool:
        return self.converged or self.iterations >= self.max_iterations

    @property
    def phase(self) -> str:
        """What the solver is doing, for a progress readout."""
        return f"{self.name} {self.iterations:,}"

    def _record(self, residual_power: np.ndarray, elapsed: float = 0.0):
        """Log the residual of the current state (power per channel, scaled units)."""
        residual = float(np.max(np.abs(residual_power) / self._norm))
        self.history.append(residual)
        self.times.append(self.seconds + elapsed)
        if residual <= self.tol:
            self.converged = True

    def step(self, count: int = 1) -> bool:
        """Do up to ``count`` units of work; True when the solve is finished."""
        t0 = time.perf_counter()
        for _ in range(count):
            if self.done:
                break
            self._advance(t0)
        self.seconds += time.perf_counter() - t0
        return self.done

    def resume(self, more_iterations: int = 0, tol: float | None = None):
        """Continue a stopped solve: raise the iteration cap and/or lower the tolerance."""
        self.max_iterations += more_iterations
        if tol is not None:
            self.tol = tol
            self.converged = self.residual <= tol

    def _advance(self, t0: float):
        raise NotImplementedError

    # -- result -------------------------------------------------------------------------------
    def _books(self):
        """(B, H, escaped, blocked, unshot) in scaled units; B = E + rho H."""
        raise NotImplementedError

    def energy(self) -> dict[str, float]:
        """Where the emitted light has gone so far, as fractions of it (worst-lit channel summed)."""
        _, H, escaped, blocked, unshot = self._books()
        absorbed = ((1.0 - self.rho) * H * self.area[:, None]).sum(axis=0, dtype=np.float64)
        total = self.emitted.sum()
        return {k: float(np.sum(v) / total) for k, v in
                (("absorbed", absorbed), ("escaped", escaped), ("blocked", blocked), ("unshot", unshot))}

    def result(self) -> SolveResult:
        B, H, escaped, blocked, unshot = self._books()
        s, area = self.scale, self.area[:, None]
        ff = self.rows.seconds - self._rows_seconds
        H64 = np.asarray(H, dtype=np.float64)
        return SolveResult(
            B=np.asarray(B, dtype=np.float64) * s, irradiance=H64 * s, iterations=self.iterations,
            converged=self.converged, residual_history=list(self.history), times=list(self.times),
            seconds={"form_factors": ff, "solve": max(self.seconds - ff, 0.0)}, method=self.name,
            emitted=self.emitted * s, absorbed=((1.0 - self.scene.rho) * H64 * area).sum(axis=0) * s,
            escaped=np.asarray(escaped, dtype=np.float64) * s, blocked=np.asarray(blocked, dtype=np.float64) * s,
            unshot=np.asarray(unshot, dtype=np.float64) * s, ambient=self._ambient() * s)

    def _ambient(self) -> np.ndarray:
        return np.zeros(3)
