"""One solve of a scene, stage by stage, free of Blender: ``Solve(SceneInput, Settings)``.

A ``SceneInput`` is what a solve needs of a scene: its triangles (a ``PatchScene``), the lights
(``lights.Light``), the World as a distant sky, two-sided emitters and the colour sources of
textured materials. ``Solve`` subdivides, adds the lights' direct light, sets up form factors
and a solver, then advances the solver in steps (``advance``), so a modal operator can run it
from a timer with a progress bar and ESC; ``finish`` gives the leaves, their radiosity B and
the vertex values. Nothing outside the object changes, so dropping it is a clean cancel. A
solve stopped at its iteration cap can be continued (``resume``) and finished again. The
Blender adapter (``blender.pipeline``) reads a scene into a ``SceneInput`` and writes results.
"""
from __future__ import annotations

import itertools
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .errors import Cancelled, SettingsError
from .formfactors.coincident import back_to_back_warning
from .formfactors.methods import FormFactors
from .hierarchy import subdivide
from .lights import Light, direct_irradiance, sky_irradiance
from .reconstruct import VertexRadiosity
from .sampling import grid_side
from .scene import PatchScene, check_writable
from .settings import QUALITY_MIN, Settings, auto_max_area
from .solvers import make_solver, patch_bytes
from .textures import varying_reflectance

#: Settings of the uniform patches and their form factors, which a hierarchical solve does not use.
UNIFORM_ONLY = ("max_area", "levels", "method", "resolution", "rotate", "split", "split_level", "rays")
#: Cosine rays per point (four an element) that sample the World in a hierarchical solve.
SKY_RAYS = 64
#: A hierarchical solve whose surfaces receive more than they send by this share of the
#: emitted power (the books' escaped below minus it) is warned of: each link's error is
#: within Quality, but at a coarse Quality their sum adds up (the furnished room at 1.0:
#: absorbed 106%, escaped -6.4%).
OVERDRAWN = 0.01


@dataclass
class SceneInput:
    """What a solve needs of a scene (the Blender adapter's ``Extraction`` is one)."""

    scene: PatchScene
    warnings: list[str] = field(default_factory=list)
    uv: np.ndarray | None = None            # (t, 3, 2) corner UVs of the triangles (NaN: none)
    corner_color: np.ndarray | None = None  # (t, 3, 3) corner colours (NaN: none)
    textures: dict = field(default_factory=dict)    # material index -> (h, w, 3) image
    attributes: dict = field(default_factory=dict)  # material index -> colour attribute name
    two_sided: set = field(default_factory=set)     # material indices that emit from both sides
    lights: list = field(default_factory=list)      # lights.Light, world space
    world: Callable | None = None                   # radiance(dirs (k, 3)) -> (k, 3) of the sky, or None


@dataclass
class Stats:
    patches: int = 0
    seconds: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)


class Solve:
    """Subdivide and prepare form factors at construction; solve with ``advance``."""

    def __init__(self, scene_input: SceneInput, settings: Settings, log=print, stats: Stats | None = None):
        self.input, self.settings, self.log = scene_input, settings, log
        self.stats = stats or Stats()
        settings.validate()
        for w in scene_input.warnings:
            log(f"RadTR warning: {w}")
        self.stats.warnings += scene_input.warnings
        rays, side = settings.vertex_gather, grid_side(settings.vertex_gather)
        if rays and side * side != rays:
            self._warn([f"Vertex Gather casts a square grid of stratified rays: {rays:,} a vertex are cast as "
                        f"{side * side:,} ({side} x {side})"])
        self.sky = None                             # the research sky's SkyFactors, once computed
        self._trace: list[tuple[float, float]] = []  # (solver seconds, residual) after each advance
        if settings.solver == "hierarchical":
            self._prepare_hierarchical()
        else:
            self._prepare_uniform()
        self.result = self.B = self.vertices = None

    def _warn(self, warnings):
        for w in warnings:
            self.log(f"RadTR warning: {w}")
        self.stats.warnings += warnings

    def _prepare_uniform(self):
        """Patches by uniform subdivision, their form factors and the chosen solver."""
        settings = self.settings
        with self._stage("subdivide"):
            base = self.input.scene
            max_area = settings.max_area or auto_max_area(base.areas.sum(), settings.levels)
            self.hierarchy = subdivide(base, max_area, settings.levels, budget_bytes=settings.cache_mb << 20,
                                       bytes_per_patch=patch_bytes(settings.solver), what=f"a {settings.solver} solve")
        self.leaves = self.hierarchy.leaves
        self.stats.patches = self.leaves.n
        if self.input.textures or self.input.attributes:
            with self._stage("textures"):
                self.leaves.rho, warnings = varying_reflectance(self.input, self.hierarchy, settings.max_reflectance)
            self.stats.warnings += warnings
        with self._stage("lights"):
            self._add_lights()
        self.leaves.validate()
        check_writable(self.leaves.emission, lambda i: f"emission of {self.leaves.patch_label(i)}")
        with self._stage("form_factor_init"):
            self.rows = FormFactors(self.leaves, settings.form_factors(), settings.cache_mb << 20)
        self._warn(self.rows.warnings)
        if settings.scheduler:
            self._on_cluster()
        with self._stage("solver_init"):
            self.solver = self._solver(self.leaves)

    def _on_cluster(self):
        """Rows from the Dask cluster ``settings.scheduler``: as many as the budget holds now
        (a shooting solve asks for one at a time), the rest when asked."""
        from .cluster import ClusterRows, connect

        with self._stage("cluster_rows"):
            self.cluster = ClusterRows(connect(self.settings.scheduler), self.leaves, self.rows.settings)
            self.rows.compute_with(self.cluster)
            held = self.rows.prefetch(np.arange(self.leaves.n))
        if held < self.leaves.n:
            self._warn([f"{held:,} of {self.leaves.n:,} form-factor rows fit the memory budget; the rest are "
                        f"computed on the cluster when a solver asks (raise Memory Budget to keep all)"])

    def _solver(self, leaves):
        s = self.settings
        return make_solver(s.solver, leaves, self.rows, tol=s.tolerance, max_iterations=s.max_iterations,
                           dtype=s.precision, user=s.user_solver)

    def _prepare_hierarchical(self):
        """Hierarchical radiosity over the input triangles (``hierarchical``): the leaves are
        made while solving; lights and the World reach each element as it is made."""
        from .hierarchical import HierarchicalRadiosity, HierarchicalSettings

        settings = self.settings
        if settings.sky != "none":
            raise SettingsError("the research sky (Sky) needs a uniform solve; use the World for a hierarchical one")
        base = self.input.scene
        if self.input.textures or self.input.attributes:
            with self._stage("textures"):
                base.rho, warnings = varying_reflectance(self.input, subdivide(base, 0.0, 0),
                                                         settings.max_reflectance)
            self.stats.warnings += warnings
        base.validate(emission_needed=False)        # the solver checks lights and the World too
        check_writable(base.emission, lambda i: f"emission of {base.patch_label(i)}")
        coincident = back_to_back_warning(base)
        if coincident:
            self._warn([coincident])
        unused = [k for k in UNIFORM_ONLY if getattr(settings, k) != getattr(Settings, k)]
        if unused:
            self._warn([f"the hierarchical solver makes its own elements and form factors: "
                        f"{', '.join(unused)} not used"])
        scene, shown = self._with_emitter_backs(base)
        with self._stage("lights"):
            external = self._external_light(scene)
        self.hierarchy, self.rows = None, None
        with self._stage("solver_init"):
            self.solver = HierarchicalRadiosity(scene, HierarchicalSettings(
                epsilon=settings.quality, tolerance=settings.tolerance, max_sweeps=settings.max_iterations,
                gather_rays=settings.vertex_gather),
                external=external, shown=shown)
        self.leaves = base

    def _emitting_backs(self, base) -> np.ndarray:
        """Ids of the emitting triangles of two-sided materials."""
        two = np.isin(base.material_index, list(self.input.two_sided))
        return np.flatnonzero(two & (base.emission.max(axis=1) > 0))

    def _with_emitter_backs(self, base):
        """``base`` plus, for two-sided emitting materials, each emitting triangle's back as an
        emitter of its own with the material's reflectance (solved, not shown: a lamp's back
        and a ceiling 1 cm above it pass light to and fro), and the mask of the triangles shown."""
        ids = self._emitting_backs(base)
        if not len(ids):
            return base, None
        tris = np.concatenate([base.triangles, base.triangles[ids][:, ::-1]])
        scene = PatchScene(base.vertices, tris, np.concatenate([base.rho, base.rho[ids]]),
                           np.concatenate([base.emission, base.emission[ids]]),
                           np.concatenate([base.object_index, base.object_index[ids]]),
                           np.concatenate([base.material_index, base.material_index[ids]]),
                           list(base.object_names), list(base.material_names))
        return scene, np.arange(scene.n) < base.n

    def _external_light(self, scene):
        """``external(tris, normals, bary=PATCH_POINTS, spread=False) -> (H, direct)``:
        irradiance (m, points, 3) of the lights and the World at barycentric points of
        elements (the World by ``SKY_RAYS`` cosine rays a point, drawn afresh at each call),
        each moved ``INSET`` towards the element's centre (a corner on the line where a wall
        meets the ceiling would see out past it), and ``direct``, the Light objects' part of
        it; or None when there are none. With ``spread``, also (a third) the same with the
        World's rays drawn alike at the points of each element (``sky_irradiance``'s
        ``shared``), whose differences are the sky's, not the rays' noise: what decides a
        split (``nodes.Nodes.init_light``). The light kept is drawn apart from it: an element
        kept because its alike rays all missed a window would keep their zero (a closed room
        lit through a window held 15-18% too little of its sky light).
        ``external.direct_at(points, normals, rng)``: the Light objects' irradiance (k, 3) at
        points on a surface, by one shadow ray a point to each light, to a point of it that
        ``rng`` draws (the gather's many rays average a penumbra; None when there are no
        Light objects): what a final-gather ray takes at the point it hits
        (``solve.HierarchicalRadiosity._gather_batch``; four fixed rays a point instead gave
        the atrium the same error, 3.85% per vertex against 3.87%, in 9 s more)."""
        from .formfactors.raycast import EmbreeRays
        from .lights import PATCH_POINTS, irradiance_at
        from .reconstruct import INSET

        self.lights = lights = self.input.lights
        sky = self.input.world
        if not lights and sky is None:
            return None
        caster = EmbreeRays(scene, SKY_RAYS)
        calls = itertools.count(1)                   # each call its own rays, the same in every run

        def external(tris, normals, bary=PATCH_POINTS, spread=False):
            k = len(bary)
            n = np.repeat(normals, k, axis=0)
            on = np.einsum("pc,ncd->npd", bary, tris)                     # (m, k, 3)
            on += INSET * (tris.mean(axis=1)[:, None] - on)
            direct = np.zeros((len(tris), k, 3))
            if lights:
                direct += irradiance_at(on.reshape(-1, 3) + caster.epsilon * n, n, lights,
                                        caster)[0].reshape(direct.shape)
            H, alike = direct.copy(), direct.copy()
            if sky is not None:                                           # a tiny triangle about each point
                small = on[:, :, None] + 1e-3 * (tris[:, None] - on[:, :, None])
                part = PatchScene(small.reshape(-1, 3), np.arange(3 * len(n)).reshape(-1, 3), 0.0, 0.0, 0, 0)
                H += sky_irradiance(part, sky, caster=caster, seed=next(calls)).reshape(H.shape)
                if spread:
                    alike += sky_irradiance(part, sky, caster=caster, seed=next(calls), shared=k).reshape(H.shape)
            return (H, direct, alike) if spread else (H, direct)

        def direct_at(points, normals, rng):
            return irradiance_at(points + caster.epsilon * normals, normals, lights, caster, rng=rng)[0]

        external.direct_at = direct_at if lights else None
        return external

    def _add_lights(self):
        """The lights' and the World's direct light, reflected once, joins the emission (``lights``)."""
        base, sky = self.input.scene, self.input.world
        backs = self._emitting_backs(base)
        tris = base.vertices[base.triangles[backs]]
        self.lights = lights = self.input.lights + [
            Light.back_of(f"back of {base.patch_label(i)}", t, base.emission[i]) for i, t in zip(backs, tris)]
        warnings = []
        H = np.zeros_like(self.leaves.emission)
        if lights:
            direct, culled = direct_irradiance(self.leaves, lights)
            H += direct
            if culled.max() > 0:
                warnings.append(f"{culled.sum():.3g} W of weak light (of Light objects, and of the backs of "
                                f"two-sided emitters) left out (culled) at patches where "
                                f"a brighter light dominates")
        if sky is not None:
            H += sky_irradiance(self.leaves, sky)
        if self.settings.sky != "none":
            H += self._apply_sky()
        if lights or sky is not None or self.settings.sky != "none":
            self.leaves.emission = self.leaves.emission + self.leaves.rho * H
        self._warn(warnings)

    def _apply_sky(self) -> np.ndarray:
        """Irradiance from the research sky (``sky``): uniform or CIE overcast, by sky form factors."""
        from .sky import cie_overcast, sky_factors, uniform_sky

        s = self.settings
        models = {"uniform": uniform_sky, "cie": cie_overcast}
        s.validate(self.leaves.n)
        self.sky = sky_factors(self.leaves, *s.sky_steps, s.sky_resolution, s.scheduler)
        if self.sky.S.nnz == 0:
            self._warn([f"the sky ({s.sky}) reaches no patch: no front face is seen from any of its "
                        f"{len(self.sky.directions):,} dome points (a closed scene, or faces turned away)"])
        return self.sky.irradiance(models[s.sky](self.sky, s.sky_radiance))

    @contextmanager
    def _stage(self, name):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.stats.seconds[name] = time.perf_counter() - t0

    @property
    def fraction(self) -> float:
        """Progress in [0, 1] on a log scale of the residual (1 at the tolerance)."""
        s = self.solver
        if s.done:
            return 1.0
        if getattr(s, "finishing", False):
            return s.finished
        r = max(s.residual, 1e-300)
        by_res = np.log(r) / np.log(max(self.settings.tolerance, 1e-300)) if r < 1 else 0.0
        return float(np.clip(max(by_res, s.iterations / s.max_iterations), 0.0, 1.0))

    @property
    def readout(self) -> str:
        """One line on where the solve stands, for the status bar, the N-panel and the CLI."""
        s = self.solver
        if getattr(s, "refining", False) or getattr(s, "finishing", False):     # no residual to speak of
            return f"{s.phase}, {s.seconds:.1f} s"
        eta = self.eta
        left = f", about {eta:,.0f} s left" if eta is not None else ""
        return f"{s.phase}: residual {s.residual:.2e} (stop at {s.tol:g}), {s.seconds:.1f} s{left}"

    @property
    def eta(self) -> float | None:
        """Seconds until the residual reaches the tolerance, at the rate its log fell over the
        latter half of the solve so far; None until it has fallen over three slices, and for a
        hierarchical solve (rounds of refining follow each solve, how many is not known)."""
        trace = self._trace
        if len(trace) < 3 or hasattr(self.solver, "refining"):
            return None
        (t0, r0), (t1, r1) = trace[len(trace) // 2 - 1], trace[-1]
        tol = max(self.solver.tol, 1e-300)
        if not (r0 > r1 > 0) or t1 <= t0:
            return None
        return max(float(np.log(r1 / tol) / (np.log(r0 / r1) / (t1 - t0))), 0.0)

    def advance(self, seconds: float = 0.1) -> bool:
        """Step the solver for about ``seconds``; True when the solve is finished."""
        end = time.perf_counter() + seconds
        try:
            while time.perf_counter() < end:
                if self.solver.step(8):
                    return True
            return self.solver.done
        finally:
            self._trace.append((self.solver.seconds, self.solver.residual))

    def resume(self, more_iterations: int):
        """Let a solve that stopped at its iteration cap go on for ``more_iterations``."""
        self.solver.resume(more_iterations)

    def run(self, progress=None) -> "Solve":
        """Solve to the end; ``progress(solve)`` after each slice may return False to cancel."""
        while not self.advance(0.25):
            if progress is not None and progress(self) is False:
                raise Cancelled("solve cancelled; nothing was changed")
        return self

    def _conclude(self):
        """The solver's result: ``leaves``, their radiosity ``B`` (what is shown: with the
        ambient term when asked) and ``vertices`` (a VertexRadiosity or the adaptive mesh's
        own vertex values)."""
        vertices = None
        if self.settings.solver == "hierarchical":
            self.adaptive = r = self.solver.result()
            self.leaves, self.result = r.leaves, r.result
            r = r.result
            self.stats.patches = self.adaptive.leaf_count
            vertices = self.adaptive.mesh_vertex_values         # gathered at the corners, if asked
            self._warn([w for w in self._overdrawn(r) if w not in self.stats.warnings])
        else:
            self.result = r = self.solver.result()
        self.stats.seconds.update(r.seconds)        # form factors and solve; refine, solve and clusters
        self.B = r.display(self.leaves.rho) if self.settings.ambient else r.B
        self.vertices = vertices or VertexRadiosity(self.leaves, self.B, self.settings.vertex_gather)

    def _overdrawn(self, r) -> list[str]:
        """A warning where the hierarchical links bring the surfaces more light than they
        send (``OVERDRAWN``), naming a finer Quality to try."""
        share = float(-(r.escaped / np.maximum(r.emitted, 1e-300)).min())
        if not share > OVERDRAWN:
            return []
        q = self.settings.quality
        return [f"the surfaces receive more light than they send, by {share:.1%} of the emitted power (the "
                f"books' escaped is negative): the links' errors, each within Quality {q:g}, add up; a finer "
                f"Quality (say {max(q / 3, QUALITY_MIN):.2g}) brings the books nearer balance"]

    def finish(self) -> "Solve":
        """Conclude the solve (``B``, ``leaves``, ``vertices``) and log its summary."""
        self._conclude()
        self.log(f"RadTR: {self.summary()}")
        return self

    def with_emission(self, E: np.ndarray) -> np.ndarray:
        """B for emission E (n, 3) on this solve's patches, with its solver settings and cached rows."""
        if self.rows is None:
            raise SettingsError("a new emission needs the form factors of a uniform solve; "
                                "the hierarchical solver keeps none")
        leaves = self.leaves.subset(np.ones(self.leaves.n, dtype=bool))
        leaves.emission = np.asarray(E, dtype=float)
        solver = self._solver(leaves)
        while not solver.step(64):
            pass
        return solver.result().B

    @property
    def instances(self) -> int:
        """How many of the meshes solved are instances (the Blender adapter knows them)."""
        return 0

    def summary(self) -> str:
        r = self.result
        unit = "shots" if r.method == "shooting" else "sweeps" if r.method != "direct" else "solve"
        state = ("converged" if r.converged else f"NOT converged to the tolerance {self.solver.tol:g}"
                 + (", stopped at the iteration cap (Continue in the panel, or more --iterations, goes on)"
                    if r.iterations >= self.solver.max_iterations
                    else ""))
        inst = f" ({self.instances:,} instances)" if self.instances else ""
        if r.method == "hierarchical":
            inst += f" ({self.adaptive.links:,} links, {len(self.adaptive.rounds)} rounds)"
        return (f"{self.stats.patches:,} patches{inst}, {r.method} {r.iterations:,} {unit}, residual {r.residual:.2e}, "
                f"{state}; {r.books(self._outside_source())}; energy balance error {r.balance_error():.1e}")

    def _outside_source(self) -> str:
        """What the books' emitted power counts besides the emitters: the light of the Light
        objects, the World and the research sky, reflected once (a scene lit by a sun alone
        "emits" that, and of a 100 W lamp what its first bounce reflects)."""
        outside = [name for name, there in (("the Light objects'", self.input.lights),
                                            ("the World's", self.input.world is not None),
                                            ("the research sky's", self.settings.sky != "none")) if there]
        return f"; {' and '.join(outside)} light counted once reflected" if outside else ""


def solve(scene_input: SceneInput, settings: Settings, log=print, progress=None) -> Solve:
    """Solve ``scene_input`` to the end (batch use); the result is in ``.leaves``, ``.B``, ``.vertices``."""
    return Solve(scene_input, settings, log).run(progress).finish()
