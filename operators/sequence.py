"""Sequence: emission files <prefix><i><suffix>, i = first..last, each solved on the last solve's
patches, shown and rendered to <out_prefix><i>.png; ESC stops and restores the colours."""
import bpy

from ..radtr_addon.blender.sequence import sequence_steps
from .session import ModalTask, last_job


class RADTR_OT_sequence(ModalTask, bpy.types.Operator):
    """Solve and render a numbered sequence of emission files (as `python -m radtr_addon sequence`)"""

    bl_idname = "radtr.sequence"
    bl_label = "Render Emission Sequence"
    what = "sequence"

    prefix: bpy.props.StringProperty(name="Prefix", subtype="FILE_PATH",
                                     description="Emission files are <prefix><i><suffix>")
    suffix: bpy.props.StringProperty(name="Suffix", default="", description="e.g. .dat")
    first: bpy.props.IntProperty(name="From", default=1)
    last: bpy.props.IntProperty(name="To", default=1)
    out_dir: bpy.props.StringProperty(name="Output Folder", subtype="DIR_PATH", default="//sequence")
    out_prefix: bpy.props.StringProperty(name="Output Prefix", default="frame_")

    def execute(self, context):
        job = last_job(self)
        if job is None:
            return {"CANCELLED"}
        return self._run_steps(context, sequence_steps(
            job, bpy.path.abspath(self.prefix), self.first, self.last, bpy.path.abspath(self.out_dir),
            self.suffix, self.out_prefix))

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def finished(self, context, result):
        self.report({"INFO"}, f"RadTR: rendered {len(result)} frame(s) into {bpy.path.abspath(self.out_dir)}")
        return {"FINISHED"}
