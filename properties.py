"""RadTR settings stored on the Scene as ``scene.radtr``."""
import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty

from .radtr_addon.blender.pipeline import Settings

_D = Settings()


def _exposure_changed(self, context):
    from .radtr_addon.blender.write import set_exposure

    set_exposure(self.exposure)


class RADTR_PG_settings(bpy.types.PropertyGroup):
    max_area: FloatProperty(
        name="Max Patch Area", default=_D.max_area, min=0.0, precision=6, unit="AREA",
        description="Largest patch area after subdivision; 0 picks one for about 2,000 patches")
    levels: IntProperty(
        name="Levels", default=_D.levels, min=0, max=12,
        description="Subdivision rounds; each halves the max area (the patch hierarchy)")
    resolution: IntProperty(
        name="Hemicube Resolution", default=_D.resolution, min=16, max=1024, step=2,
        description="Pixels across a hemicube face: more is more exact and slower")
    tolerance: FloatProperty(
        name="Tolerance", default=_D.tolerance, min=1e-9, max=0.5, precision=6,
        description="Stop when the unshot power falls below this fraction of the emitted power")
    max_iterations: IntProperty(
        name="Max Shots", default=_D.max_iterations, min=1,
        description="Stop after this many shooting steps")
    max_reflectance: FloatProperty(
        name="Max Reflectance", default=_D.max_reflectance, min=0.0, max=0.999,
        description="Reflectances above this are clamped, with a warning naming the material")
    exposure: FloatProperty(
        name="Exposure", default=_D.exposure, min=0.0, soft_max=16.0, update=_exposure_changed,
        description="Brightness factor of every RadTR display (radiance shown = exposure x B / pi)")
    mode: EnumProperty(
        name="Result", default=_D.mode,
        items=[("COPY", "Copies", "Subdivided copies in a 'RadTR' collection; sources hidden"),
               ("REPLACE", "Replace", "Give the source objects the subdivided meshes")])

    def to_settings(self) -> Settings:
        return Settings(max_area=self.max_area, levels=self.levels,
                        resolution=self.resolution - self.resolution % 2,
                        tolerance=self.tolerance, max_iterations=self.max_iterations,
                        max_reflectance=self.max_reflectance, exposure=self.exposure, mode=self.mode)


_register, _unregister = bpy.utils.register_classes_factory((RADTR_PG_settings,))


def register():
    _register()
    bpy.types.Scene.radtr = PointerProperty(type=RADTR_PG_settings)


def unregister():
    del bpy.types.Scene.radtr
    _unregister()
