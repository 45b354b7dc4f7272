"""One solve of a Blender scene, stage by stage: the code the operators and the CLI share.

``SolveJob`` reads the scene, subdivides, sets up form factors and a solver, then advances
the solver in steps (``advance``), so the Solve operator can run it from a modal timer with
a progress bar and ESC; ``finish`` writes the result. Until ``finish`` nothing in the file
changes, so dropping the job is a clean cancel. A job stopped at its iteration cap can be
continued (``resume``) and finished again.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..errors import SettingsError
from ..formfactors.methods import FormFactors, FormFactorSettings
from ..hierarchy import subdivide
from ..lights import Light, direct_irradiance, sky_irradiance
from ..reconstruct import VertexRadiosity
from ..scene import PatchScene
from ..solvers import make_solver, patch_bytes
from ..textures import varying_reflectance
from .extract import extract, source_objects
from .lights import scene_lights, world_radiance
from .write import check_replaceable, check_writable, write_results

#: Cosine rays per point (four an element) that sample the World in a hierarchical solve.
SKY_RAYS = 64
#: Default patch count used to pick ``max_area`` when it is 0 (auto).
AUTO_PATCHES = 2000
#: Peak bytes per Embree ray in flight (a form-factor row or a vertex gather; measured).
BYTES_PER_RAY = 160
#: Bytes per GPU view pixel: RGBA32F target, readback, per-pixel layout and histogram keys.
BYTES_PER_PIXEL = 80
#: Bytes per dome point (direction, position, solid angle) and per sky form factor.
BYTES_PER_DOME_POINT, BYTES_PER_SKY_FACTOR = 56, 12


@dataclass
class Settings:
    """What a solve does; the Scene PropertyGroup and the CLI flags mirror these fields."""

    max_area: float = 0.0          # scene units^2; 0 picks total area / AUTO_PATCHES
    levels: int = 1
    method: str = "hemicube"       # form factors: hemicube | paraboloid | embree
    resolution: int = 64           # hemicube pixels across the full face / paraboloid disk
    rotate: bool = False           # hemicube: random turn about the normal per patch
    split: str = "adaptive"        # paraboloid: none | uniform | adaptive
    split_level: int = 4           # paraboloid uniform split N
    rays: int = 1024               # embree rays per row
    solver: str = "shooting"       # shooting | jacobi | gauss_seidel | direct | user | hierarchical
    quality: float = 0.03          # hierarchical: link error bound / the scene's mean emitted exitance
    user_solver: str = ""          # solver "user": module:function or file.py:function
    tolerance: float = 1e-3        # residual (unshot) power / emitted power
    max_iterations: int = 20_000   # shots or sweeps
    precision: str = "float64"     # accumulation: float32 | float64
    ambient: bool = False          # shooting: show unshot light as Cohen's ambient term
    gather_rays: int = 0           # vertex radiosity by a final gather of this many rays (0: patch mean)
    sky: str = "none"              # apply a sky through sky form factors: none | uniform | cie
    sky_radiance: float = 1.0      # uniform radiance, or the CIE sky's zenith radiance (W/m^2/sr)
    sky_step: float = 10.0         # dome points every this many degrees of azimuth and altitude
    sky_resolution: int = 256      # parallel rays across the scene per dome point
    max_reflectance: float = 0.95
    exposure: float = 1.0
    mode: str = "COPY"             # or "REPLACE"
    cache_mb: int = 2048

    def validate(self, patches: int = 0):
        """Raise SettingsError naming the first setting out of range, or the work that would
        need more memory than ``cache_mb`` (the sky's form factors only once ``patches`` is known)."""
        from ..solvers import SOLVERS

        self.form_factors().validate()
        s = self
        for label, value, ok, need in (
                ("max area", s.max_area, s.max_area >= 0 and np.isfinite(s.max_area), "0 (auto) or more"),
                ("levels", s.levels, s.levels >= 0, "0 or more"),
                ("resolution", s.resolution, s.resolution >= 2, "at least 2"),
                ("solver", s.solver, s.solver in (*SOLVERS, "user", "hierarchical"),
                 f"one of {', '.join(SOLVERS)}, user or hierarchical"),
                ("quality", s.quality, 1e-4 <= s.quality <= 1,
                 "between 1e-4 and 1 (smaller: finer, slower; Quality 0.01 solves the bundled furnished room "
                 "in minutes)"),
                ("tolerance", s.tolerance, 0 <= s.tolerance < np.inf, "0 or more"),
                ("iterations", s.max_iterations, s.max_iterations >= 1, "at least 1"),
                ("precision", s.precision, s.precision in ("float32", "float64"), "float32 or float64"),
                ("gather rays", s.gather_rays, s.gather_rays >= 0, "0 (patch mean) or more"),
                ("sky", s.sky, s.sky in ("none", "uniform", "cie"), "none, uniform or cie"),
                ("sky radiance", s.sky_radiance, 0 <= s.sky_radiance < np.inf, "0 or more"),
                ("sky step", s.sky_step, 0 < s.sky_step <= 90, "above 0 and at most 90 degrees"),
                ("max reflectance", s.max_reflectance, 0 <= s.max_reflectance <= 1, "between 0 and 1"),
                ("exposure", s.exposure, 0 <= s.exposure < np.inf, "0 or more"),
                ("result mode", s.mode, s.mode in ("COPY", "REPLACE"), "COPY or REPLACE"),
                ("memory budget", s.cache_mb, s.cache_mb >= 1, "at least 1 MB")):
            if not ok:
                raise SettingsError(f"{label} must be {need}, got {value!r}")
        for what, need in self.memory(patches).items():
            if need > self.cache_mb << 20:
                raise SettingsError(f"{what} needs {need / 2**30:,.1f} GiB, over the memory budget of "
                                    f"{self.cache_mb:,} MB (raise the budget: Memory Budget, --cache-mb)")

    def memory(self, patches: int = 0) -> dict[str, int]:
        """Bytes the largest arrays of each stage need, by what they are for."""
        from ..sky import dome_size

        out = {}
        if self.method == "embree":
            out[f"casting {self.rays:,} rays per patch"] = self.rays * BYTES_PER_RAY
        else:
            pixels = self.resolution ** 2 * (3 if self.method == "hemicube" else 1)
            out[f"a {self.method} view of {pixels:,} pixels (resolution {self.resolution})"] = pixels * BYTES_PER_PIXEL
        out[f"gathering {self.gather_rays:,} rays per vertex"] = self.gather_rays * BYTES_PER_RAY
        if self.sky != "none":
            points = dome_size(self.sky_step, self.sky_step)
            rows = min(self.sky_resolution ** 2, patches)
            seen = f" x {rows:,} patches" if patches else ""
            out[f"a sky dome of {points:,} points (step {self.sky_step:g} degrees){seen}"] = (
                points * (BYTES_PER_DOME_POINT + BYTES_PER_SKY_FACTOR * rows))
        return out

    def form_factors(self) -> FormFactorSettings:
        return FormFactorSettings(method=self.method, resolution=self.resolution, rotate=self.rotate,
                                  split=self.split, split_level=self.split_level, rays=self.rays)


@dataclass
class Stats:
    patches: int = 0
    seconds: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)


def auto_max_area(total_area: float, levels: int, patches: int = AUTO_PATCHES) -> float:
    """``max_area`` giving about ``patches`` leaves after ``levels`` rounds."""
    return 2 * total_area / patches * 2 ** max(levels - 1, 0)


class SolveJob:
    """Extract, subdivide and prepare form factors at construction; shoot with ``advance``."""

    def __init__(self, bl_scene, depsgraph, view_layer, settings: Settings, log=print):
        self.bl_scene, self.settings, self.log, self.view_layer = bl_scene, settings, log, view_layer
        self.stats = Stats()
        settings.validate()
        with self._stage("extract"):
            objects = source_objects(bl_scene, view_layer)
            if settings.mode == "REPLACE":
                check_replaceable(objects)
            self.extraction = extract(depsgraph, objects, settings.max_reflectance)
        for w in self.extraction.warnings:
            log(f"RadTR warning: {w}")
        self.stats.warnings += self.extraction.warnings
        if settings.solver == "hierarchical":
            self._prepare_hierarchical()
        else:
            self._prepare_uniform()
        self.result = None
        self.objects = []                       # the result objects, once written

    def _prepare_uniform(self):
        """Patches by uniform subdivision, their form factors and the chosen solver."""
        settings, log = self.settings, self.log
        with self._stage("subdivide"):
            base = self.extraction.scene
            max_area = settings.max_area or auto_max_area(base.areas.sum(), settings.levels)
            self.hierarchy = subdivide(base, max_area, settings.levels, budget_bytes=settings.cache_mb << 20,
                                       bytes_per_patch=patch_bytes(settings.solver), what=f"a {settings.solver} solve")
        self.leaves = self.hierarchy.leaves
        self.stats.patches = self.leaves.n
        if self.extraction.textures or self.extraction.attributes:
            with self._stage("textures"):
                self.leaves.rho, warnings = varying_reflectance(self.extraction, self.hierarchy,
                                                                settings.max_reflectance)
            self.stats.warnings += warnings
        with self._stage("lights"):
            self._add_lights(self.bl_scene, self.view_layer)
        self.leaves.validate()
        check_writable(self.leaves.emission, lambda i: f"emission of {self.leaves.patch_label(i)}")
        with self._stage("form_factor_init"):
            self.rows = FormFactors(self.leaves, settings.form_factors(), settings.cache_mb << 20)
        for w in self.rows.warnings:
            log(f"RadTR warning: {w}")
        self.stats.warnings += self.rows.warnings
        with self._stage("solver_init"):
            self.solver = make_solver(settings.solver, self.leaves, self.rows, tol=settings.tolerance,
                                      max_iterations=settings.max_iterations, dtype=settings.precision,
                                      user=settings.user_solver)

    def _prepare_hierarchical(self):
        """Hierarchical radiosity over the input triangles (``hierarchical``): the leaves are
        made while solving; lights and the World reach each element as it is made."""
        from ..hierarchical import HierarchicalRadiosity, HierarchicalSettings

        settings = self.settings
        if settings.sky != "none":
            raise SettingsError("the research sky (Sky) needs a uniform solve; use the World for a hierarchical one")
        base = self.extraction.scene
        if self.extraction.textures or self.extraction.attributes:
            with self._stage("textures"):
                base.rho, warnings = varying_reflectance(self.extraction, subdivide(base, 0.0, 0),
                                                         settings.max_reflectance)
            self.stats.warnings += warnings
        base.validate(emission_needed=False)        # the solver checks lights and the World too
        check_writable(base.emission, lambda i: f"emission of {base.patch_label(i)}")
        scene, shown = self._with_emitter_backs(base)
        with self._stage("lights"):
            external = self._external_light(scene)
        self.hierarchy, self.rows = None, None
        with self._stage("solver_init"):
            self.solver = HierarchicalRadiosity(scene, HierarchicalSettings(
                epsilon=settings.quality, tolerance=settings.tolerance, max_sweeps=settings.max_iterations),
                external=external, shown=shown)
        self.leaves = base

    def _with_emitter_backs(self, base):
        """``base`` plus, for two-sided emitting materials, each emitting triangle's back as an
        emitter of its own with the material's reflectance (solved, not shown: a lamp's back
        and a ceiling 1 cm above it pass light to and fro), and the mask of the triangles shown."""
        two = np.isin(base.material_index, list(self.extraction.two_sided))
        ids = np.flatnonzero(two & (base.emission.max(axis=1) > 0))
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
        """``external(tris, normals, bary=PATCH_POINTS)``: irradiance (m, points, 3) of the
        Light objects and the World at barycentric points of elements (the World by
        ``SKY_RAYS`` cosine rays a point), each moved ``INSET`` towards the element's centre
        (a corner on the line where a wall meets the ceiling would see out past it), or None
        when there are none."""
        from ..formfactors.raycast import EmbreeRays
        from ..lights import PATCH_POINTS, irradiance_at
        from ..reconstruct import INSET

        lights, warnings = scene_lights(self.bl_scene, self.view_layer)
        sky, sky_warnings = world_radiance(self.bl_scene)
        for w in warnings + sky_warnings:
            self.log(f"RadTR warning: {w}")
        self.stats.warnings += warnings + sky_warnings
        self.lights = lights
        if not lights and sky is None:
            return None
        caster = EmbreeRays(scene, SKY_RAYS)

        def external(tris, normals, bary=PATCH_POINTS):
            k = len(bary)
            n = np.repeat(normals, k, axis=0)
            on = np.einsum("pc,ncd->npd", bary, tris)                     # (m, k, 3)
            on += INSET * (tris.mean(axis=1)[:, None] - on)
            H = np.zeros((len(tris), k, 3))
            if lights:
                H += irradiance_at(on.reshape(-1, 3) + caster.epsilon * n, n, lights, caster)[0].reshape(H.shape)
            if sky is not None:                                           # a tiny triangle about each point
                small = on[:, :, None] + 1e-3 * (tris[:, None] - on[:, :, None])
                part = PatchScene(small.reshape(-1, 3), np.arange(3 * len(n)).reshape(-1, 3), 0.0, 0.0, 0, 0)
                H += sky_irradiance(part, sky, caster=caster).reshape(H.shape)
            return H
        return external

    def _add_lights(self, bl_scene, view_layer):
        """Light objects' and the World's direct light, reflected once, joins the emission (``lights``)."""
        lights, warnings = scene_lights(bl_scene, view_layer)
        lights += self._emitter_backs()
        sky, sky_warnings = world_radiance(bl_scene)
        warnings += sky_warnings
        self.lights = lights
        H = np.zeros_like(self.leaves.emission)
        if lights:
            direct, culled = direct_irradiance(self.leaves, lights)
            H += direct
            if culled.max() > 0:
                warnings.append(f"{culled.sum():.3g} W of weak light left out (culled) at patches where "
                                f"a brighter light dominates")
        if sky is not None:
            H += sky_irradiance(self.leaves, sky)
        if self.settings.sky != "none":
            H += self._apply_sky()
        if lights or sky is not None or self.settings.sky != "none":
            self.leaves.emission = self.leaves.emission + self.leaves.rho * H
        for w in warnings:
            self.log(f"RadTR warning: {w}")
        self.stats.warnings += warnings

    def _apply_sky(self) -> np.ndarray:
        """Irradiance from the research sky (``sky``): uniform or CIE overcast, by sky form factors."""
        from ..sky import cie_overcast, sky_factors, uniform_sky

        s = self.settings
        models = {"uniform": uniform_sky, "cie": cie_overcast}
        s.validate(self.leaves.n)
        self.sky = sky_factors(self.leaves, s.sky_step, s.sky_step, s.sky_resolution)
        return self.sky.irradiance(models[s.sky](self.sky, s.sky_radiance))

    def _emitter_backs(self) -> list:
        """The backs of emitting input triangles with two-sided materials, as area lights."""
        base = self.extraction.scene
        two = np.isin(base.material_index, list(self.extraction.two_sided))
        ids = np.flatnonzero(two & (base.emission.max(axis=1) > 0))
        tris = base.vertices[base.triangles[ids]]
        return [Light.back_of(f"back of {base.patch_label(i)}", t, base.emission[i]) for i, t in zip(ids, tris)]

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
        r = max(s.residual, 1e-300)
        by_res = np.log(r) / np.log(max(self.settings.tolerance, 1e-300)) if r < 1 else 0.0
        return float(np.clip(max(by_res, s.iterations / s.max_iterations), 0.0, 1.0))

    @property
    def readout(self) -> str:
        """One line on where the solve stands, for the status bar and the N-panel."""
        s = self.solver
        return (f"{s.phase}: residual {s.residual:.2e} (stop at {s.tol:g}), "
                f"{s.seconds:.1f} s")

    def advance(self, seconds: float = 0.1) -> bool:
        """Step the solver for about ``seconds``; True when the solve is finished."""
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            if self.solver.step(8):
                return True
        return self.solver.done

    def resume(self, more_iterations: int):
        """Let a solve that stopped at its iteration cap go on for ``more_iterations``."""
        self.solver.resume(more_iterations)

    def run(self, progress=None) -> "SolveJob":
        """Solve to the end; ``progress(job)`` after each slice may return False to cancel."""
        from ..errors import Cancelled

        while not self.advance(0.25):
            if progress is not None and progress(self) is False:
                raise Cancelled("solve cancelled; nothing was changed")
        return self

    def finish(self) -> list:
        """Write the result into the file; returns the result objects."""
        self.result = r = self.solver.result()
        vertices = None
        if self.settings.solver == "hierarchical":
            self.adaptive, self.result = r, r.result
            self.leaves, r = r.leaves, r.result
            self.stats.patches = self.adaptive.leaf_count
            if not self.settings.gather_rays:
                vertices = self.adaptive.mesh_vertex_values
        self.stats.seconds.update(r.seconds)        # form factors and solve; refine, solve and clusters
        B = r.display(self.leaves.rho) if self.settings.ambient else r.B
        vertices = vertices or VertexRadiosity(self.leaves, B, self.settings.gather_rays)
        with self._stage("write"):
            self.objects = objects = write_results(self.bl_scene, self.extraction, self.leaves, B,
                                                   self.settings.exposure, self.settings.mode, vertices)
        if self.settings.gather_rays:
            self.stats.seconds["vertex_gather"] = vertices.seconds
            self.stats.seconds["write"] -= vertices.seconds
        self.log(f"RadTR: {self.summary()}")
        return objects

    @property
    def instances(self) -> int:
        """How many of the meshes solved are instances."""
        return sum(1 for src in self.extraction.objects if src.instance)

    def summary(self) -> str:
        r = self.result
        unit = "shots" if r.method == "shooting" else "sweeps" if r.method != "direct" else "solve"
        state = ("converged" if r.converged else f"NOT converged to the tolerance {self.solver.tol:g}"
                 + (", stopped at the iteration cap (Continue goes on)" if r.iterations >= self.solver.max_iterations
                    else ""))
        inst = f" ({self.instances:,} instances)" if self.instances else ""
        if r.method == "hierarchical":
            inst += f" ({self.adaptive.links:,} links, {len(self.adaptive.rounds)} rounds)"
        return (f"{self.stats.patches:,} patches{inst}, {r.method} {r.iterations:,} {unit}, residual {r.residual:.2e}, "
                f"{state}; energy balance error {r.balance_error():.1e}")


def solve(context, settings: Settings, log=print, progress=None) -> SolveJob:
    """Solve the context's scene to completion and write the result (batch use)."""
    job = SolveJob(context.scene, context.evaluated_depsgraph_get(), context.view_layer, settings, log)
    job.run(progress)
    job.finish()
    return job
