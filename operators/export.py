"""Export: the last solve's form factors (and low-rank U, V; the sky matrix and its points when
the solve has them) to .npz, .mat or the seed's text files, with progress and ESC."""
import bpy

from ..radtr_addon.tasks import export_steps
from .session import ModalTask, last_job

SUFFIXES = {"NPZ": ".npz", "MAT": ".mat", "TEXT": ""}


class RADTR_OT_export(ModalTask, bpy.types.Operator):
    """Write the last solve's matrices for other programs: F, E, rho, areas, triangles, U and V, the sky"""

    bl_idname = "radtr.export"
    bl_label = "Export Matrices"
    what = "export"

    filepath: bpy.props.StringProperty(subtype="FILE_PATH")
    format: bpy.props.EnumProperty(name="Format", default="NPZ", items=[
        ("NPZ", "NumPy (.npz)", "One .npz file, sparse matrices as CSR arrays"),
        ("MAT", "MATLAB (.mat)", "One .mat file, F and V sparse"),
        ("TEXT", "Seed text files", "<path>_ffs.dat, _U.dat, ... as the seed wrote them")])
    level: bpy.props.IntProperty(name="Low-Rank Level", default=-1, min=-1, max=12,
                                 description="Also U and V of this hierarchy level; -1: none")
    refine_to: bpy.props.IntProperty(name="Refine To", default=0, min=0,
                                     description="Refine the level's clusters where the light is until there are "
                                                 "this many (the multi-level cut); 0: the level as it is")

    def execute(self, context):
        job = last_job(self)
        if job is None:
            return {"CANCELLED"}
        path = bpy.path.abspath(self.filepath)
        path = path.removesuffix(".npz").removesuffix(".mat") + SUFFIXES[self.format]
        self._path = path
        level = self.level if self.level >= 0 else None
        return self._run_steps(context, export_steps(job, path, level, self.refine_to, job.sky,
                                                     log=lambda line: self.report({"WARNING"}, line)))

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def finished(self, context, result):
        self.report({"INFO"}, f"RadTR: wrote {len(result)} file(s) at {self._path}")
        return {"FINISHED"}
