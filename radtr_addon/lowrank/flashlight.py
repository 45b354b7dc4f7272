"""The flashlight: a spot light whose first bounce the low-rank solve carries every frame.

A spot at ``position`` aimed along ``direction`` with cone half-angle ``angle`` and
intensity I (W/sr, times ``color``) gives patch i, centre c_i at distance r, the direct
irradiance H_i = I cos(theta_i) / r^2 when c_i is inside the cone, faces the spot and an
Embree shadow ray reaches it. That light, reflected, E_i = rho_i H_i, joins the scene's own
emission as the right-hand side of B = E + R K B, solved by the low-rank back-end. Several
spots add their light. ``Flashlight.frame`` times each stage (visibility, solve).

Lighting scenarios (day, night, lamps on) are solved radiosities of the same patches, kept
and blended with weights: B is linear in the emission, so with scenarios a frame is
sum w_s B_s plus the low-rank solve of the spots' light alone, and the scene's own light is
as exact as the solves that made the scenarios.

Shadow rays are the per-frame cost that grows with the lit patches. With ``ShadowGroups``
(planar nodes of the patch hierarchy, at most ``GROUP_PATCHES`` patches each) a frame rays each
lit group's centre and the patches at its three corners, and rays every lit patch of a group
only where those disagree: a shadow edge is found where it crosses a group; a shadow that
falls wholly inside a group, between its samples, is missed (``bench realtime`` counts the
patches that differ from a ray per patch).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from .backends import DEFAULT_BACKEND, make_backend


@dataclass
class Spot:
    position: np.ndarray
    direction: np.ndarray
    angle: float = np.radians(20.0)     # cone half-angle: the flashlight's size
    intensity: float = 1.0              # W/sr
    color: np.ndarray = field(default_factory=lambda: np.ones(3))


#: Most patches in a shadow group (``ShadowGroups.from_hierarchy``).
GROUP_PATCHES = 32


@dataclass
class ShadowGroups:
    """Patches in planar groups, each with 4 sample patches (its centre and the patches
    nearest its three corners) whose shadow rays stand for the whole group when they agree."""

    group: np.ndarray       # (n,) group of each patch
    samples: np.ndarray     # (groups, 4) patch ids; -1 for groups too small to sample

    @classmethod
    def from_hierarchy(cls, hierarchy, patches: int = GROUP_PATCHES) -> "ShadowGroups":
        """Each patch's group: its coarsest hierarchy node with at most ``patches`` patches (a
        planar triangle: the nodes stay inside their input triangle)."""
        leaves = hierarchy.leaves
        group = np.full(leaves.n, -1, dtype=np.int64)
        corners, centres = [], []
        for level in range(hierarchy.levels + 1):
            node = hierarchy.cluster[level]
            size = np.bincount(node)
            take = (group < 0) & (size[node] <= patches)
            if take.any():
                nodes, local = np.unique(node[take], return_inverse=True)
                group[take] = sum(len(c) for c in centres) + local
                corners.append(leaves.vertices[hierarchy.level_triangles[level][nodes]])
                centres.append(hierarchy.representative[level][nodes])
        corners = np.concatenate(corners)                                  # (groups, 3, 3)
        samples = [np.concatenate(centres)]
        for k in range(3):
            dist = np.linalg.norm(leaves.centroids - corners[group, k], axis=1)
            order = np.lexsort((dist, group))
            first = order[np.r_[True, group[order][1:] != group[order][:-1]]]
            nearest = np.empty(len(corners), dtype=np.int64)
            nearest[group[first]] = first
            samples.append(nearest)
        samples = np.stack(samples, axis=1)
        samples[np.bincount(group) < 2 * samples.shape[1]] = -1        # a ray a patch is fewer
        return cls(group, samples)


def _clear_from(caster, position, points) -> np.ndarray:
    return caster.clear_between(np.broadcast_to(position, points.shape), points)


def spot_visible(centroids, position, lit: np.ndarray, caster, groups: ShadowGroups | None = None) -> np.ndarray:
    """Which of the patches ``lit`` (ids into ``centroids``) a shadow ray from ``position``
    reaches (bool per id); with ``groups``, rays per patch only in groups whose samples disagree."""
    c = centroids
    if groups is None or not len(lit):
        return _clear_from(caster, position, c[lit])
    touched = np.zeros(len(groups.samples), dtype=bool)
    touched[groups.group[lit]] = True
    state = np.full(len(groups.samples), 2, dtype=np.int8)        # 0 hidden, 1 seen, 2 ray each
    ids = np.flatnonzero(touched & (groups.samples[:, 0] >= 0))
    samples, back = np.unique(groups.samples[ids], return_inverse=True)
    clear = _clear_from(caster, position, c[samples])[back.reshape(-1)].reshape(len(ids), groups.samples.shape[1])
    state[ids] = np.where(clear.all(axis=1), 1, np.where(clear.any(axis=1), 2, 0))
    per_lit = state[groups.group[lit]]
    visible = per_lit == 1
    mixed = per_lit == 2
    visible[mixed] = _clear_from(caster, position, c[lit[mixed]])
    return visible


def spot_light(scene, spot: Spot, caster, groups: ShadowGroups | None = None, centroids=None):
    """The patches ``spot`` lights (ids) and the irradiance (m, 3) at their centres, with
    shadow rays (per patch, or per ``groups`` where their samples agree); ``centroids``: the
    scene's, when already at hand. Only the cone's patches get more than a dot product."""
    centroids = scene.centroids if centroids is None else centroids
    d = centroids - spot.position
    r2 = np.einsum("ij,ij->i", d, d)
    along = d @ (spot.direction / np.linalg.norm(spot.direction))
    facing = -np.einsum("ij,ij->i", d, scene.normals)
    lit = np.flatnonzero((along > 0) & (along * along >= np.cos(spot.angle) ** 2 * r2) & (facing > 0))
    if len(lit):
        lit = lit[spot_visible(centroids, spot.position, lit, caster, groups)]
    r2 = r2[lit]
    return lit, np.outer(spot.intensity * facing[lit] / (r2 * np.sqrt(r2)), spot.color)


def spot_irradiance(scene, spot: Spot, caster, groups: ShadowGroups | None = None) -> np.ndarray:
    """Direct irradiance (n, 3) from ``spot`` at the patch centres: H = I cos / r^2 where
    inside the cone, facing it and reached by a shadow ray (``spot_light``)."""
    H = np.zeros((scene.n, 3))
    lit, values = spot_light(scene, spot, caster, groups)
    H[lit] = values
    return H


@dataclass
class Scenario:
    """A solved radiosity of the patches, shown ``weight`` times."""

    name: str
    B: np.ndarray           # (n, 3)
    weight: float = 1.0


def blend(scenarios, n: int) -> np.ndarray:
    """sum weight x B (n, 3) over ``scenarios``."""
    out = np.zeros((n, 3))
    for sc in scenarios:
        out += sc.weight * sc.B
    return out


def _name_of(backend) -> str:
    """The registered name of a back-end object (after a fallback it is not the one asked for)."""
    from .backends import BACKENDS

    return next(name for name, cls in BACKENDS.items() if type(backend) is cls)


class Flashlight:
    """Per-frame B for spots over a solved patch scene, colour or mono, on a chosen back-end."""

    def __init__(self, scene, lowrank, backend: str = DEFAULT_BACKEND, dtype=np.float32, user: str = "", warn=None,
                 groups: ShadowGroups | None = None):
        from ..formfactors.raycast import EmbreeRays

        self.scene, self.backend_name, self.dtype, self.user = scene, backend, dtype, user
        self.groups = groups
        self._centroids = scene.centroids
        self._caster = EmbreeRays(scene, 1)
        self._colour = lowrank
        self._mono = None
        self.mono = False
        self.backend = make_backend(backend, lowrank, dtype, user, fallback=True, warn=warn)
        self.backend_name = self.backend_name if self.backend_name == "user" else _name_of(self.backend)
        self.seconds = {"visibility": 0.0, "solve": 0.0}
        self.frames = 0
        self.scenarios: list[Scenario] = []     # when set (set_scenarios), the scene's light is their blend
        self._base = None

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

    def set_scenarios(self, scenarios: list[Scenario]):
        """Show the blend of ``scenarios`` (solved on these patches) as the scene's own light;
        none: the scene's emission, solved by the low-rank factors."""
        for sc in scenarios:
            if sc.B.shape != self.scene.emission.shape:
                raise SceneError(f"lighting scenario '{sc.name}' has {len(sc.B):,} patches, the solve "
                                 f"{self.scene.n:,}: it was solved on other patches")
        self.scenarios = list(scenarios)
        self._base = blend(scenarios, self.scene.n) if scenarios else None

    def emission(self, spots) -> np.ndarray:
        """The right-hand side: the scene's emission (none when scenarios stand for it) plus
        the reflected light of ``spots`` (a Spot or several)."""
        s = self.scene
        E = np.zeros_like(s.emission) if self.scenarios else s.emission.copy()
        for spot in [spots] if isinstance(spots, Spot) else spots:
            lit, H = spot_light(s, spot, self._caster, self.groups, self._centroids)
            E[lit] += s.rho[lit] * H
        return E.mean(axis=1, keepdims=True) if self.mono else E

    def frame(self, spot) -> tuple[np.ndarray, dict]:
        """B (n, 3) for ``spot`` (a Spot or several; grey in mono), and this frame's seconds
        per stage."""
        t0 = time.perf_counter()
        E = self.emission(spot)
        t1 = time.perf_counter()
        B = self.backend.solve(E)
        if self._base is not None:
            B = B + (self._base.mean(axis=1, keepdims=True) if self.mono else self._base)
        t2 = time.perf_counter()
        stages = {"visibility": t1 - t0, "solve": t2 - t1}
        for k, v in stages.items():
            self.seconds[k] += v
        self.frames += 1
        return (np.repeat(B, 3, axis=1) if self.mono else B), stages
