"""RadTR settings stored on the Scene as ``scene.radtr``."""
import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from .radtr_addon.hierarchical.solve import GATHER_ADAPTIVE
from .radtr_addon.lowrank.backends import BACKENDS, DEFAULT_BACKEND
from .radtr_addon.settings import AUTO_GATHER_RAYS, QUALITY_MIN, Settings, auto_gather_rays

_D = Settings()


def _display_changed(self, context):
    from .radtr_addon.blender.write import set_display

    set_display(context.scene, self.display, self.exposure)


def _scenario_weight_changed(self, context):
    from .operators.session import running
    from .radtr_addon.blender.scenarios import show_blend

    job = running["last"]
    if job is not None and job.objects and running["job"] is None:
        for w in show_blend(context.scene.radtr, job):
            print(f"RadTR: {w}")


class RADTR_PG_scenario(bpy.types.PropertyGroup):
    """A stored lighting scenario (its B is the item's ``B`` custom property)."""

    weight: FloatProperty(
        name="Weight", default=0.0, min=0.0, soft_max=2.0, update=_scenario_weight_changed,
        description="How much of this scenario's light the result meshes and the flashlight show")


class RADTR_PG_view(bpy.types.PropertyGroup):
    """A saved viewpoint (``radtr_addon.blender.viewpoints``): the viewport's target, turn, distance, lens."""

    location: FloatVectorProperty(name="Target", size=3, subtype="TRANSLATION")
    rotation: FloatVectorProperty(name="Rotation", size=4, subtype="QUATERNION", default=(1.0, 0.0, 0.0, 0.0))
    distance: FloatProperty(name="Distance", default=10.0, min=0.0)
    lens: FloatProperty(name="Lens", default=50.0, min=1.0, description="Focal length in mm (36 mm sensor)")


class RADTR_PG_settings(bpy.types.PropertyGroup):
    max_area: FloatProperty(
        name="Max Patch Area", default=_D.max_area, min=0.0, precision=6, unit="AREA",
        description="Largest patch area after subdivision; 0 picks one for about 2,000 patches")
    levels: IntProperty(
        name="Levels", default=_D.levels, min=0, max=12,
        description="Subdivision rounds; each halves the max area (the patch hierarchy)")
    method: EnumProperty(
        name="Form Factors", default=_D.method,
        items=[("hemicube", "Hemicube", "Five GPU views per patch with exact pixel weights"),
               ("paraboloid", "Paraboloid", "One GPU hemisphere view per patch, edges split to follow the curve"),
               ("embree", "Rays", "Embree rays on the CPU: no GPU needed")])
    resolution: IntProperty(
        name="Resolution", default=_D.resolution, min=16, max=1024, step=2,
        description="Pixels across a hemicube face or the paraboloid disk: more is more exact and slower")
    rotate: BoolProperty(
        name="Random Rotation", default=_D.rotate,
        description="Turn each hemicube about its normal at random to break aliasing")
    split: EnumProperty(
        name="Split", default=_D.split,
        items=[("none", "None", "Plain projection: straight edges, darker junctions"),
               ("triangle", "Triangle", "Longest-edge bisection, edges cut in N rounded up to a power of 2"),
               ("centre", "Centre", "A fan of 3N triangles from the centroid, edges cut in N"),
               ("uniform", "Uniform", "Every triangle drawn as an N x N grid (the seed's homogeneous split)"),
               ("diagonal", "Diagonal", "A zigzag strip of 3N - 2 triangles, edges cut in N"),
               ("adaptive", "Adaptive", "Each triangle split by how wide it looks from the patch")])
    split_level: IntProperty(
        name="Split N", default=_D.split_level, min=1, max=64,
        description="Split level N of the triangle, centre, uniform and diagonal splits")
    rays: IntProperty(
        name="Rays", default=_D.rays, min=1, soft_max=65536,
        description="Rays per patch (rounded to a square number): error falls as 1 / sqrt(rays)")
    solver: EnumProperty(
        name="Solver", default=_D.solver,
        items=[("shooting", "Shooting", "Progressive refinement: brightest patch first, any scene size"),
               ("jacobi", "Jacobi", "Gathering sweeps, every patch from the last sweep's light"),
               ("gauss_seidel", "Gauss-Seidel", "Gathering sweeps using light updated in the same sweep"),
               ("direct", "Direct", "Sparse/dense LU of the whole system: exact, for small scenes"),
               ("user", "User", "Your own Python function: module:function or file.py:function"),
               ("hierarchical", "Hierarchical", "Adaptive patches and links: refined only where light changes "
                "(contacts, shadows, near fields); Quality sets how far")])
    quality: FloatProperty(
        name="Quality", default=_D.quality, min=QUALITY_MIN, max=1.0, precision=4,
        description="Hierarchical: error allowed per link, as a fraction of the scene's mean emitted exitance "
                    "(smaller: more patches and links, slower, closer)")
    user_solver: StringProperty(
        name="Function", default=_D.user_solver,
        description="module:function or path/to/file.py:function called as f(F=, E=, rho=, areas=) -> B")
    tolerance: FloatProperty(
        name="Tolerance", default=_D.tolerance, min=1e-12, max=0.5, precision=6,
        description="Stop when the residual (unshot) power falls below this fraction of the emitted power")
    max_iterations: IntProperty(
        name="Max Iterations", default=_D.max_iterations, min=1,
        description="Stop after this many shots (shooting) or sweeps (gathering, and per round of "
                    "hierarchical); Continue goes on")
    precision: EnumProperty(
        name="Precision", default=_D.precision,
        items=[("float64", "Double", "Accumulate in float64"),
               ("float32", "Single", "Accumulate in float32: less memory traffic, about 1e-6 relative error")])
    ambient: BoolProperty(
        name="Ambient Term", default=_D.ambient,
        description="Shooting: add the light not yet shot as an even ambient term when showing a partial solve")
    gather_rays: IntProperty(
        name="Vertex Gather", default=_D.gather_rays, min=-1, soft_max=4096,
        description="Rays per vertex for a final gather of the solved light into the vertex colours "
                    "(sharper corners and shadows); 0 shows the mean of the patches around each vertex "
                    f"(hierarchical: each leaf's quadratic; from {GATHER_ADAPTIVE} rays the count is a mean, "
                    "more where the light is noisier); -1 is auto: "
                    f"{AUTO_GATHER_RAYS} with the hierarchical solver up to Quality 0.1, fewer coarser "
                    f"({auto_gather_rays(1.0)} at 1), 0 with the others")
    lowrank_level: IntProperty(
        name="Low-Rank Level", default=1, min=0, max=12,
        description="Hierarchy level whose nodes are the flashlight's clusters: finer is more exact, "
                    "slower to precompute and to update (solve with Levels above it)")
    lowrank_refine: IntProperty(
        name="Refine To", default=0, min=0, soft_max=8192,
        description="Split the level's clusters that carry the most light until there are this many "
                    "(several levels combined: more exact at the same size); 0 keeps the level as it is")
    lowrank_backend: EnumProperty(
        name="Back-End", default=DEFAULT_BACKEND,
        items=[(name, cls.label, cls.description) for name, cls in BACKENDS.items()]
        + [("user", "User", "Your own function every frame: f(E=, U=, V=, rho=) -> B")])
    lowrank_user: StringProperty(
        name="Frame Function", default="",
        description="module:function or file.py:function the User back-end calls every frame")
    sky: EnumProperty(
        name="Sky", default=_D.sky,
        items=[("none", "None", "No research sky (the World still lights the scene)"),
               ("uniform", "Uniform", "A uniform sky dome, through sky form factors"),
               ("cie", "CIE Overcast", "L = Lz (1 + 2 cos theta) / 3, through sky form factors")])
    sky_radiance: FloatProperty(
        name="Sky Radiance", default=_D.sky_radiance, min=0.0,
        description="Uniform sky radiance, or the CIE sky's zenith radiance (W/m^2/sr)")
    sky_step: FloatProperty(
        name="Dome Step", default=_D.sky_step, min=0.5, max=90.0,
        description="Degrees between dome points in azimuth (the seed's alpha): smaller is more exact and slower")
    sky_altitude_step: FloatProperty(
        name="Altitude Step", default=_D.sky_altitude_step, min=0.0, max=90.0,
        description="Degrees between the dome's altitude bands (the seed's beta); 0: the same as the Dome Step")
    sky_resolution: IntProperty(
        name="Sky Rays Across", default=_D.sky_resolution, min=16, soft_max=2048,
        description="Parallel rays across the scene per dome point: more finds smaller patches in the sun")
    max_reflectance: FloatProperty(
        name="Max Reflectance", default=_D.max_reflectance, min=0.0, max=1.0,
        description="Reflectances above this are clamped, with a warning naming the material; 1 is "
                    "accepted where light can escape")
    exposure: FloatProperty(
        name="Exposure", default=_D.exposure, min=0.0, soft_max=16.0, update=_display_changed,
        description="Brightness factor of every RadTR display (radiance shown = exposure x B / pi)")
    display: EnumProperty(
        name="Display", default="interpolated", update=_display_changed,
        items=[("interpolated", "Interpolated", "Radiosity interpolated over the vertices"),
               ("flat", "Flat", "Each patch's own radiosity"),
               ("emission", "Emission", "What each patch emits"),
               ("patch_id", "Patch IDs", "Each patch in its id colour code (i + 1 as bytes)"),
               ("outlines", "Outlines", "Interpolated radiosity with the patch edges drawn")])
    view_patch: IntProperty(
        name="Patch", default=0, min=0, description="Patch index for the debug view and View from Patch")
    view_kind: EnumProperty(
        name="View", default="paraboloid",
        items=[("paraboloid", "Paraboloid", "The hemisphere map the paraboloid method draws"),
               ("hemicube", "Hemicube", "The unfolded hemicube"),
               ("sky", "Sky", "The sky's parallel view from the dome point along the patch's normal")])
    cache_mb: IntProperty(
        name="Memory Budget (MB)", default=_D.cache_mb, min=1,
        description="Memory the form factors and the largest work arrays may take; larger work is "
                    "refused, with the size it needs, before it starts")
    scheduler: StringProperty(
        name="Dask Scheduler", default=_D.scheduler,
        description="Compute form-factor rows on a Dask cluster: local:N (N worker processes here) or "
                    "tcp://HOST:PORT; empty: in Blender's process")
    scenarios: CollectionProperty(type=RADTR_PG_scenario)
    views: CollectionProperty(type=RADTR_PG_view)
    mode: EnumProperty(
        name="Result", default=_D.mode,
        items=[("COPY", "Copies", "Subdivided copies in a 'RadTR' collection; sources hidden"),
               ("REPLACE", "Replace", "Give the source objects the subdivided meshes")])

    def to_settings(self) -> Settings:
        """The solve's Settings: every field of the schema from the property of its name."""
        settings = Settings.of(self)
        settings.resolution -= settings.resolution % 2        # a hemicube face needs an even count
        return settings


_register, _unregister = bpy.utils.register_classes_factory((RADTR_PG_scenario, RADTR_PG_view, RADTR_PG_settings))


def register():
    _register()
    bpy.types.Scene.radtr = PointerProperty(type=RADTR_PG_settings)


def unregister():
    del bpy.types.Scene.radtr
    _unregister()
