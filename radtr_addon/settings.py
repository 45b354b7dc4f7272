"""The settings of a solve, in one schema: ``Settings``.

Each field carries its default, its choices and its help; the command line builds its flags
from them (``cli``), the Blender properties are checked against them (``tests/test_settings``)
and copied field by field (``properties.to_settings``). Defaults of the form-factor knobs are
``FormFactorSettings``'s own and Quality is ``HierarchicalSettings``'s epsilon, so a solve, a
bench and an engine call agree.
"""
from __future__ import annotations

import argparse
from dataclasses import MISSING, dataclass, field, fields

import numpy as np

from .errors import SettingsError
from .formfactors.methods import METHODS, SPLIT_MODES, FormFactorSettings
from .hierarchical import HierarchicalSettings
from .solvers import ALL_SOLVERS

#: Default patch count used to pick ``max_area`` when it is 0 (auto).
AUTO_PATCHES = 2000
#: Final gather rays per vertex of a hierarchical solve when Vertex Gather is -1 (auto), at
#: Quality 0.1 and finer: its links' own corner values put a box near a hot, mostly hidden
#: ceiling patch 3-11% bright; gathered, within 2% (per-vertex noise 3.6% at 256 rays, 8% and
#: blotches at 64). Coarser Quality takes fewer (``auto_gather_rays``).
AUTO_GATHER_RAYS = 256
#: The finest Quality (hierarchical epsilon) a solve takes.
QUALITY_MIN = 1e-4


def auto_gather_rays(quality: float) -> int:
    """Auto final gather rays at a Quality: ``AUTO_GATHER_RAYS`` to 0.1, about halved over the
    decade to 1 (144 there), where the links' own error is as large as the gather's noise
    (the atrium at Quality 1.0 against Cycles: 4.05% per vertex at 128 rays in 35 s, 3.88%
    at 256 in 54 s); a square, the stratified grid a vertex's rays are cast on."""
    side = np.sqrt(AUTO_GATHER_RAYS) * min(1.0, (0.1 / max(quality, QUALITY_MIN)) ** (np.log10(2) / 2))
    return int(np.ceil(side - 1e-9)) ** 2

#: Peak bytes per Embree ray in flight (a form-factor row or a vertex gather; measured).
BYTES_PER_RAY = 160
#: Bytes per GPU view pixel: RGBA32F target, readback, per-pixel layout and histogram keys.
BYTES_PER_PIXEL = 80
#: Bytes per dome point (direction, position, solid angle) and per sky form factor.
BYTES_PER_DOME_POINT, BYTES_PER_SKY_FACTOR = 56, 12
SKIES = ("none", "uniform", "cie")
PRECISIONS = ("float64", "float32")
RESULT_MODES = ("COPY", "REPLACE")

_FF = FormFactorSettings()
_HR = HierarchicalSettings()


def option(default, help: str, choices: tuple | None = None, flag: str | None = None):
    """A settings field: its default, the help the CLI prints, its choices, and its CLI flag
    when it is not ``--<name-with-dashes>``."""
    return field(default=default, metadata={"help": help, "choices": choices, "flag": flag})


@dataclass
class Settings:
    """What a solve does. The Scene's RadTR properties and the CLI flags are these fields."""

    max_area: float = option(0.0, f"largest patch area in scene units^2 (0: about {AUTO_PATCHES:,} patches)")
    levels: int = option(1, "subdivision rounds; each halves the max area (the patch hierarchy)")
    method: str = option(_FF.method, "form-factor method", METHODS)
    resolution: int = option(_FF.resolution, "hemicube face / paraboloid disk pixels")
    rotate: bool = option(_FF.rotate, "hemicube: random turn about each normal")
    split: str = option(_FF.split, "paraboloid: how triangles are split to follow the curve", SPLIT_MODES)
    split_level: int = option(_FF.split_level, "paraboloid split level N (triangle, centre, uniform, diagonal)")
    rays: int = option(_FF.rays, "embree rays per patch")
    solver: str = option("shooting", "radiosity solver (hierarchical: adaptive patches and links, see --quality)",
                         ALL_SOLVERS)
    quality: float = option(_HR.epsilon, "hierarchical: error bound of a link / mean emitted exitance "
                                  "(smaller: finer, slower)")
    user_solver: str = option("", "with --solver user: module:function or file.py:function (see examples/)")
    tolerance: float = option(1e-3, "residual (unshot) power / emitted power to stop at")
    max_iterations: int = option(100_000, "most shots or sweeps (hierarchical: sweeps per round)",
                                 flag="--iterations")
    precision: str = option("float64", "accumulation precision", PRECISIONS)
    ambient: bool = option(False, "shooting: show unshot light as Cohen's ambient term")
    gather_rays: int = option(-1, "final gather of the vertex colours with this many rays per vertex "
                                  f"(-1: auto, {AUTO_GATHER_RAYS} with hierarchical up to Quality 0.1, fewer "
                                  f"coarser ({auto_gather_rays(1.0)} at 1), none otherwise; with "
                                  "hierarchical a mean, more where the light is noisier; "
                                  "0: none, the patch mean, or with hierarchical each leaf's quadratic)")
    sky: str = option("none", "apply a research sky through sky form factors", SKIES)
    sky_radiance: float = option(1.0, "uniform radiance, or the CIE sky's zenith radiance (W/m^2/sr)")
    sky_step: float = option(10.0, "dome points every this many degrees of azimuth (the seed's alpha)")
    sky_altitude_step: float = option(0.0, "dome bands every this many degrees of altitude (the seed's beta); "
                                           "0: the same as the azimuth step")
    sky_resolution: int = option(256, "parallel rays across the scene per dome point")
    max_reflectance: float = option(0.95, "reflectances above this are clamped, with a warning naming the material")
    exposure: float = option(1.0, "brightness of the displayed result (radiance shown = exposure x B / pi)")
    mode: str = option("COPY", "result: subdivided copies (COPY) or the sources' own meshes (REPLACE)",
                       RESULT_MODES)
    cache_mb: int = option(2048, "memory budget in MB for form factors and work arrays")
    scheduler: str = option("", "compute form-factor rows on a Dask cluster: local:N (N worker processes here) or "
                                "tcp://HOST:PORT; empty: in this process")

    @classmethod
    def of(cls, source) -> "Settings":
        """Settings from any object with these fields as attributes (CLI args, Blender properties)."""
        return cls(**{f.name: getattr(source, f.name) for f in fields(cls)})

    def validate(self, patches: int = 0):
        """Raise SettingsError naming the first setting out of range, or the work that would
        need more memory than ``cache_mb`` (the sky's form factors only once ``patches`` is known)."""
        s = self
        for f in fields(self):
            choices = f.metadata["choices"]
            if choices and getattr(self, f.name) not in choices:
                raise SettingsError(f"{f.name.replace('_', ' ')} must be one of {', '.join(choices)}, "
                                    f"got {getattr(self, f.name)!r}")
        self.form_factors().validate()
        if self.scheduler:
            from .cluster import parse

            parse(self.scheduler)
        for label, value, ok, need in (
                ("max area", s.max_area, s.max_area >= 0 and np.isfinite(s.max_area), "0 (auto) or more"),
                ("levels", s.levels, s.levels >= 0, "0 or more"),
                ("resolution", s.resolution, s.resolution >= 2, "at least 2"),
                ("quality", s.quality, QUALITY_MIN <= s.quality <= 1,
                 "between 1e-4 and 1 (smaller: finer, slower; at 0.1 the bundled furnished room takes "
                 "about 1.5 minutes, at 0.03 over 10)"),
                ("tolerance", s.tolerance, 0 <= s.tolerance < np.inf, "0 or more"),
                ("iterations", s.max_iterations, s.max_iterations >= 1, "at least 1"),
                ("gather rays", s.gather_rays, s.gather_rays >= -1, "-1 (auto), 0 (none) or more"),
                ("sky radiance", s.sky_radiance, 0 <= s.sky_radiance < np.inf, "0 or more"),
                ("sky step", s.sky_step, 0 < s.sky_step <= 90, "above 0 and at most 90 degrees"),
                ("sky altitude step", s.sky_altitude_step, 0 <= s.sky_altitude_step <= 90,
                 "0 (the azimuth step) or at most 90 degrees"),
                ("max reflectance", s.max_reflectance, 0 <= s.max_reflectance <= 1, "between 0 and 1"),
                ("exposure", s.exposure, 0 <= s.exposure < np.inf, "0 or more"),
                ("memory budget", s.cache_mb, s.cache_mb >= 1, "at least 1 MB"),
                ("scheduler", s.scheduler, not s.scheduler or s.solver != "hierarchical",
                 "empty with the hierarchical solver (it computes its links in this process)"),
                ("scheduler", s.scheduler, not s.scheduler or s.method == "embree",
                 "empty with a GPU form-factor method (Dask workers have no GPU context): use --method embree")):
            if not ok:
                raise SettingsError(f"{label} must be {need}, got {value!r}")
        for what, need in self.memory(patches).items():
            if need > self.cache_mb << 20:
                size = f"{need / 2**30:,.1f} GiB" if need >= 2**30 else f"{need / 2**20:,.0f} MB"
                raise SettingsError(f"{what} needs {size}, over the memory budget of "
                                    f"{self.cache_mb:,} MB (raise the budget: Memory Budget, --cache-mb)")

    def memory(self, patches: int = 0) -> dict[str, int]:
        """Bytes the largest arrays of each stage need, by what they are for."""
        from .sky import dome_size

        out = {}
        if self.method == "embree":
            out[f"casting {self.rays:,} rays per patch"] = self.rays * BYTES_PER_RAY
        else:
            pixels = self.resolution ** 2 * (3 if self.method == "hemicube" else 1)
            out[f"a {self.method} view of {pixels:,} pixels (resolution {self.resolution})"] = pixels * BYTES_PER_PIXEL
        out[f"gathering {self.vertex_gather:,} rays per vertex"] = self.vertex_gather * BYTES_PER_RAY
        if self.sky != "none":
            points = dome_size(*self.sky_steps)
            rows = min(self.sky_resolution ** 2, patches)
            seen = f" x {rows:,} patches" if patches else ""
            out[f"a sky dome of {points:,} points (steps {self.sky_steps[0]:g} x {self.sky_steps[1]:g} "
                f"degrees){seen}"] = (
                points * (BYTES_PER_DOME_POINT + BYTES_PER_SKY_FACTOR * rows))
        return out

    @property
    def vertex_gather(self) -> int:
        """Final gather rays per vertex, auto (-1) resolved for the solver."""
        if self.gather_rays >= 0:
            return self.gather_rays
        return auto_gather_rays(self.quality) if self.solver == "hierarchical" else 0

    @property
    def sky_steps(self) -> tuple[float, float]:
        """(alpha, beta): the dome's azimuth and altitude steps in degrees."""
        return self.sky_step, self.sky_altitude_step or self.sky_step

    def form_factors(self) -> FormFactorSettings:
        return FormFactorSettings(method=self.method, resolution=self.resolution, rotate=self.rotate,
                                  split=self.split, split_level=self.split_level, rays=self.rays)


def add_arguments(parser):
    """One ``argparse`` flag per ``Settings`` field (``--max-area`` ...), defaults and choices
    from the schema; ``Settings.of(args)`` reads them back."""
    for f in fields(Settings):
        flag = f.metadata["flag"] or "--" + f.name.replace("_", "-")
        default = f.default if f.default is not MISSING else None
        if f.type in (bool, "bool"):
            parser.add_argument(flag, dest=f.name, action=argparse.BooleanOptionalAction, default=default,
                                help=f.metadata["help"])
            continue
        kind = {"float": float, "int": int, "str": str}[f.type if isinstance(f.type, str) else f.type.__name__]
        parser.add_argument(flag, dest=f.name, type=kind, default=default, choices=f.metadata["choices"],
                            help=f.metadata["help"])


def auto_max_area(total_area: float, levels: int, patches: int = AUTO_PATCHES) -> float:
    """``max_area`` giving about ``patches`` leaves after ``levels`` rounds."""
    return 2 * total_area / patches * 2 ** max(levels - 1, 0)
