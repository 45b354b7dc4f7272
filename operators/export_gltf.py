"""Export glTF: the last solve's result meshes to a .glb/.gltf with their light as vertex colours."""
import bpy
from bpy_extras.io_utils import ExportHelper

from ..radtr_addon.blender.gltf import export_gltf
from ..radtr_addon.errors import user_message
from .session import last_job


class RADTR_OT_export_gltf(bpy.types.Operator, ExportHelper):
    """Write the solved meshes to glTF: COLOR_0 the radiance shown (exposure x B / pi), _RADTR_RADIOSITY B"""

    bl_idname = "radtr.export_gltf"
    bl_label = "Export glTF"

    filename_ext = ".glb"
    filter_glob: bpy.props.StringProperty(default="*.glb;*.gltf", options={"HIDDEN"})

    def execute(self, context):
        job = last_job(self)
        if job is None:
            return {"CANCELLED"}
        try:
            warnings = export_gltf(context.scene, job.objects, self.filepath, context.scene.radtr.exposure)
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        for w in warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"RadTR: wrote {self.filepath}")
        return {"FINISHED"}
