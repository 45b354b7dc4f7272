"""The flashlight: a spot light whose first bounce the low-rank solve carries every frame.

A spot at ``position`` aimed along ``direction`` with cone half-angle ``angle`` and
intensity I (W/sr, times ``color``) gives patch i, centre c_i at distance r, the direct
irradiance H_i = I cos(theta_i) / r^2 when c_i is inside the cone, faces the spot and an
Embree shadow ray reaches it. That light, reflected, E_i = rho_i H_i, joins the scene's own
emission as the right-hand side of B = E + R K B, solved by the low-rank back-end.
``Flashlight.frame`` times each stage (visibility, solve).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .backends import make_backend


@dataclass
class Spot:
    position: np.ndarray
    direction: np.ndarray
    angle: float = np.radians(20.0)     # cone half-angle: the flashlight's size
    intensity: float = 1.0              # W/sr
    color: np.ndarray = field(default_factory=lambda: np.ones(3))


def spot_irradiance(scene, spot: Spot, caster) -> np.ndarray:
    """Direct irradiance (n, 3) from ``spot`` at the patch centres, with shadow rays."""
    d = scene.centroids - spot.position
    r = np.linalg.norm(d, axis=1)
    u = d / np.maximum(r, 1e-300)[:, None]
    direction = spot.direction / np.linalg.norm(spot.direction)
    cos_patch = -np.einsum("ij,ij->i", u, scene.normals)
    lit = np.flatnonzero((u @ direction >= np.cos(spot.angle)) & (cos_patch > 0) & (r > 0))
    H = np.zeros((scene.n, 3))
    if len(lit):
        seen = lit[caster.clear_between(np.broadcast_to(spot.position, (len(lit), 3)), scene.centroids[lit])]
        H[seen] = np.outer(spot.intensity * cos_patch[seen] / r[seen] ** 2, spot.color)
    return H


def _name_of(backend) -> str:
    """The registered name of a back-end object (after a fallback it is not the one asked for)."""
    from .backends import BACKENDS

    return next(name for name, cls in BACKENDS.items() if type(backend) is cls)


class Flashlight:
    """Per-frame B for spots over a solved patch scene, colour or mono, on a chosen back-end."""

    def __init__(self, scene, lowrank, backend: str = "numpy", dtype=np.float32, user: str = "", warn=None):
        from ..formfactors.raycast import EmbreeRays

        self.scene, self.backend_name, self.dtype, self.user = scene, backend, dtype, user
        self._caster = EmbreeRays(scene, 1)
        self._colour = lowrank
        self._mono = None
        self.mono = False
        self.backend = make_backend(backend, lowrank, dtype, user, fallback=True, warn=warn)
        self.backend_name = self.backend_name if self.backend_name == "user" else _name_of(self.backend)
        self.seconds = {"visibility": 0.0, "solve": 0.0}
        self.frames = 0

    @property
    def lowrank(self):
        """The colour factors (mono ones are derived from them)."""
        return self._colour

    def set_mono(self, mono: bool):
        if mono == self.mono:
            return
        if mono and self._mono is None:
            self._mono = self._colour.monochrome()
        self.mono = mono
        self.backend = make_backend(self.backend_name, self._mono if mono else self._colour, self.dtype, self.user)

    def emission(self, spot: Spot) -> np.ndarray:
        """The right-hand side: the scene's emission plus the reflected spot light."""
        s = self.scene
        E = s.emission + s.rho * spot_irradiance(s, spot, self._caster)
        return E.mean(axis=1, keepdims=True) if self.mono else E

    def frame(self, spot: Spot) -> tuple[np.ndarray, dict]:
        """B (n, 3) for ``spot`` (grey in mono), and this frame's seconds per stage."""
        t0 = time.perf_counter()
        E = self.emission(spot)
        t1 = time.perf_counter()
        B = self.backend.solve(E)
        t2 = time.perf_counter()
        stages = {"visibility": t1 - t0, "solve": t2 - t1}
        for k, v in stages.items():
            self.seconds[k] += v
        self.frames += 1
        return (np.repeat(B, 3, axis=1) if self.mono else B), stages
