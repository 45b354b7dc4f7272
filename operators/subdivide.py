"""Subdivide: show the patches a solve would use, each in its own colour."""
import bpy
import numpy as np

from ..radtr_addon.blender.extract import extract, source_objects
from ..radtr_addon.blender.write import write_results
from ..radtr_addon.errors import RadTRError
from ..radtr_addon.hierarchy import subdivide
from ..radtr_addon.settings import auto_max_area


def patch_colours(n: int) -> np.ndarray:
    """Distinct colours per patch (golden-ratio hues), scaled so exposure 1 shows them as is."""
    hue = (np.arange(n) * 0.6180339887) % 1.0
    rgb = np.clip(np.abs((hue[:, None] * 6 + [0, 4, 2]) % 6 - 3) - 1, 0, 1)
    return np.pi * (0.25 + 0.75 * rgb)


class RADTR_OT_subdivide(bpy.types.Operator):
    """Split the visible meshes into patches (the patch hierarchy) and show them"""

    bl_idname = "radtr.subdivide"
    bl_label = "Subdivide"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        s = context.scene.radtr.to_settings()
        try:
            ex = extract(context.evaluated_depsgraph_get(),
                         source_objects(context.scene, context.view_layer), s.max_reflectance)
            max_area = s.max_area or auto_max_area(ex.scene.areas.sum(), s.levels)
            h = subdivide(ex.scene, max_area, s.levels)
            write_results(context.scene, ex, h.leaves, patch_colours(h.leaves.n), s.exposure, s.mode)
        except RadTRError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"RadTR: {ex.scene.n} triangles -> {h.leaves.n} patches "
                              f"in {h.levels} levels")
        return {"FINISHED"}
