"""PatchScene: the triangles a solve works on, as float64 numpy arrays.

Units: emission ``E`` and radiosity ``B`` are exitances in W/m^2 per RGB channel
(radiance L = B / pi); reflectance ``rho`` is the diffuse albedo in [0, 1] (1 only where light can still leave:
``solvers.check_energy_decays``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import SceneError

#: Triangles whose area is below this fraction of the mean area are degenerate.
DEGENERATE_AREA_FRACTION = 1e-12
#: The largest value a float32 colour attribute holds.
FLOAT32_MAX = float(np.finfo(np.float32).max)


def triangle_geometry(vertices: np.ndarray, triangles: np.ndarray):
    """Unit normals (n, 3) and areas (n,) of triangles (n, 3) indexing vertices (v, 3)."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    cross = np.cross(b - a, c - a)
    twice_area = np.linalg.norm(cross, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        normals = cross / twice_area[:, None]
    return normals, 0.5 * twice_area


def check_writable(values: np.ndarray, label):
    """Raise SceneError when a row of ``values`` (k, 3) is NaN or beyond float32; ``label(i)`` names row i."""
    bad = ~(np.abs(values) <= FLOAT32_MAX).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        shown = ", ".join(f"{v:.3g}" for v in values[i])
        raise SceneError(f"{label(i)}: ({shown}) W/m^2 is NaN or beyond what a colour attribute holds "
                         f"({FLOAT32_MAX:.3g}), {int(bad.sum())} in all; lower the emission; nothing was written")


@dataclass
class PatchScene:
    """Triangle patches with their surface properties.

    Attributes
    ----------
    vertices : (v, 3) float64, world space
    triangles : (n, 3) int64, counter-clockwise seen from the emitting/reflecting side
    rho : (n, 3) float64 diffuse reflectance
    emission : (n, 3) float64 exitance, W/m^2
    object_index, material_index : (n,) int64 into ``object_names`` / ``material_names``
    """

    vertices: np.ndarray
    triangles: np.ndarray
    rho: np.ndarray
    emission: np.ndarray
    object_index: np.ndarray
    material_index: np.ndarray
    object_names: list[str] = field(default_factory=list)
    material_names: list[str] = field(default_factory=list)
    normals: np.ndarray = field(init=False)
    areas: np.ndarray = field(init=False)

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.triangles = np.ascontiguousarray(self.triangles, dtype=np.int64).reshape(-1, 3)
        n = len(self.triangles)
        self.rho = np.array(np.broadcast_to(self.rho, (n, 3)), dtype=np.float64)
        self.emission = np.array(np.broadcast_to(self.emission, (n, 3)), dtype=np.float64)
        self.object_index = np.broadcast_to(np.asarray(self.object_index, dtype=np.int64), (n,)).copy()
        self.material_index = np.broadcast_to(np.asarray(self.material_index, dtype=np.int64), (n,)).copy()
        self.normals, self.areas = triangle_geometry(self.vertices, self.triangles)

    @property
    def n(self) -> int:
        return len(self.triangles)

    @property
    def centroids(self) -> np.ndarray:
        return self.vertices[self.triangles].mean(axis=1)

    def emitted_power(self) -> np.ndarray:
        """Total emitted power per channel, W."""
        return (self.emission * self.areas[:, None]).sum(axis=0)

    def patch_label(self, i: int) -> str:
        """Human-readable name of patch ``i`` for error messages."""
        obj = self.object_names[self.object_index[i]] if self.object_names else "?"
        mat = self.material_names[self.material_index[i]] if self.material_names else "?"
        return f"patch {i} (object '{obj}', material '{mat}')"

    def validate(self, emission_needed: bool = True):
        """Raise SceneError naming the first offending patch when the scene cannot be solved
        (``emission_needed``: also when nothing emits; a solve whose light comes from Light
        objects or the World checks that itself)."""
        if self.n == 0:
            raise SceneError("the scene has no triangles to solve")
        if not np.all(np.isfinite(self.vertices)):
            raise SceneError("vertex coordinates contain NaN or infinity")
        checks = [
            (~np.isfinite(self.emission).all(axis=1), "emission is NaN or infinite"),
            ((self.emission < 0).any(axis=1), "emission is negative"),
            (~np.isfinite(self.rho).all(axis=1), "reflectance is NaN or infinite"),
            ((self.rho < 0).any(axis=1), "reflectance is negative"),
            ((self.rho > 1).any(axis=1), "reflectance is over 1 (it would create light)"),
            (~(self.areas > 0), "triangle has zero area"),
        ]
        for bad, what in checks:
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise SceneError(f"{self.patch_label(i)}: {what} ({int(bad.sum())} patches in all)")
        if emission_needed and not np.any(self.emission > 0):
            raise SceneError("nothing emits light: give a material emission (Emission Strength > 0) "
                             "or add a light that reaches a surface")

    def without_degenerate(self) -> tuple["PatchScene", int]:
        """A copy without zero-area triangles, and how many were dropped."""
        mean = self.areas.mean() if self.n else 0.0
        keep = self.areas > DEGENERATE_AREA_FRACTION * mean
        dropped = int((~keep).sum())
        if dropped == 0:
            return self, 0
        return self.subset(keep), dropped

    def subset(self, keep: np.ndarray) -> "PatchScene":
        """The patches selected by the boolean mask ``keep`` (vertices shared as they are)."""
        return PatchScene(
            self.vertices, self.triangles[keep], self.rho[keep], self.emission[keep],
            self.object_index[keep], self.material_index[keep],
            list(self.object_names), list(self.material_names),
        )
