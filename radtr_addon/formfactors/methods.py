"""One interface over every form-factor method: ``FormFactors(scene, settings).row(i)``.

``FormFactorSettings`` names the method and its knobs; ``FormFactors`` builds the method,
falls back from a GPU method to Embree rays when no GPU context can be had (with a
warning), warns about faces modelled twice, back to back (``coincident``), and is the
``RowCache`` of its rows within a byte budget.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import GPUUnavailable, SettingsError
from .coincident import back_to_back_warning
from .rows import RowCache

METHODS = ("hemicube", "paraboloid", "embree")
GPU_METHODS = ("hemicube", "paraboloid")
#: Paraboloid: how each triangle is split before projection (see ``paraboloid``), in the seed's
#: order (report 4.5.1, Anexo J): none, triangle (longest edge), centre, uniform (the seed's
#: homogeneous), diagonal, adaptive (ours, for the seed's tessellation shader).
SPLIT_MODES = ("none", "triangle", "centre", "uniform", "diagonal", "adaptive")
#: Split modes whose depth ``split_level`` sets.
LEVELLED_SPLITS = ("triangle", "centre", "uniform", "diagonal")
#: Paraboloid adaptive split: the largest arc-chord gap, in disk radii.
DEFAULT_SPLIT_TOLERANCE = 2e-3


@dataclass
class FormFactorSettings:
    """Method and knobs; the ones a method does not use are ignored."""

    method: str = "hemicube"
    resolution: int = 64           # hemicube pixels across the full face / paraboloid disk
    rotate: bool = False           # hemicube: random turn about the normal per patch
    split: str = "adaptive"        # paraboloid: one of SPLIT_MODES
    split_level: int = 4           # paraboloid triangle / centre / uniform / diagonal: level N
    split_tolerance: float = DEFAULT_SPLIT_TOLERANCE
    rays: int = 1024               # embree: rays per row
    seed: int = 0                  # embree jitter and hemicube rotation
    origins: str = "area"          # embree: ray origins over the patch or at its centroid

    def label(self) -> str:
        if self.method == "hemicube":
            return f"hemicube {self.resolution}" + (" rotated" if self.rotate else "")
        if self.method == "paraboloid":
            split = self.split
            if split in LEVELLED_SPLITS:
                split = f"{split} {self.split_level}"
            elif split == "adaptive":
                split = f"adaptive {self.split_tolerance:g}"
            return f"paraboloid {self.resolution} split {split}"
        return f"embree {self.rays} rays"

    def validate(self):
        if self.method not in METHODS:
            raise SettingsError(f"form-factor method must be one of {', '.join(METHODS)}, got '{self.method}'")
        if self.method == "hemicube" and (self.resolution < 2 or self.resolution % 2):
            raise SettingsError(f"hemicube resolution must be even and >= 2, got {self.resolution}")
        if self.split not in SPLIT_MODES:
            raise SettingsError(f"split mode must be one of {', '.join(SPLIT_MODES)}, got '{self.split}'")
        if not 1 <= self.split_level <= 64:
            raise SettingsError(f"split level must be 1 to 64, got {self.split_level}")
        if self.rays < 1:
            raise SettingsError(f"rays per row must be at least 1, got {self.rays}")


def make_method(scene, settings: FormFactorSettings):
    """The renderer/caster for ``settings``; GPU methods need ``ensure_gpu_context`` first."""
    settings.validate()
    if settings.method == "hemicube":
        from .hemicube import HemicubeRenderer

        return HemicubeRenderer(scene, settings.resolution, rotate=settings.rotate, seed=settings.seed)
    if settings.method == "paraboloid":
        from .paraboloid import ParaboloidRenderer

        return ParaboloidRenderer(scene, settings.resolution, settings.split, settings.split_level,
                                  settings.split_tolerance)
    from .raycast import EmbreeRays

    return EmbreeRays(scene, settings.rays, settings.seed, settings.origins)


class FormFactors(RowCache):
    """Rows F[i, :] of a PatchScene by the method ``settings`` names, cached within ``cache_bytes``."""

    def __init__(self, scene, settings: FormFactorSettings | None = None, cache_bytes: int = 2 << 30,
                 fallback: bool = True):
        self.scene = scene
        self.settings = settings or FormFactorSettings()
        self.warnings: list[str] = []
        if self.settings.method in GPU_METHODS:
            from .gpu_context import ensure_gpu_context

            try:
                ensure_gpu_context()
            except GPUUnavailable as exc:
                if not fallback:
                    raise
                self.warnings.append(f"{exc}; using Embree rays ({self.settings.rays} per row) instead")
                self.settings = FormFactorSettings(**{**vars(self.settings), "method": "embree"})
        self.method = make_method(scene, self.settings)
        super().__init__(self.method.rows, cache_bytes)
        coincident = back_to_back_warning(scene)
        if coincident:
            self.warnings.append(coincident)
