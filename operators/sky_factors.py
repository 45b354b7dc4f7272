"""Sky Form Factors: the sky matrix of the last solve's patches (alpha and beta steps), kept for
Export, and on request one picture a dome point (patch ids in colour code, as the seed saved them)."""
import bpy

from ..radtr_addon.tasks import sky_steps
from .session import ModalTask, last_job


class RADTR_OT_sky_factors(ModalTask, bpy.types.Operator):
    """Compute the sky form factors of the last solve's patches (Export writes them)"""

    bl_idname = "radtr.sky_factors"
    bl_label = "Sky Form Factors"
    what = "sky form factors"

    alpha: bpy.props.FloatProperty(name="Azimuth Step", default=10.0, min=0.5, max=90.0,
                                   description="Degrees between dome points in azimuth (alpha)")
    beta: bpy.props.FloatProperty(name="Altitude Step", default=10.0, min=0.5, max=90.0,
                                  description="Degrees between the dome's altitude bands (beta)")
    resolution: bpy.props.IntProperty(name="Rays Across", default=256, min=16, soft_max=2048,
                                      description="Parallel rays across the scene per dome point")
    images: bpy.props.BoolProperty(name="Save Views", default=False,
                                   description="One PNG a dome point: what it sees, patch ids in colour code")
    out_dir: bpy.props.StringProperty(name="Views Folder", subtype="DIR_PATH", default="//sky_views")

    def execute(self, context):
        job = last_job(self)
        if job is None:
            return {"CANCELLED"}
        self._job = job
        folder = bpy.path.abspath(self.out_dir) if self.images else None
        return self._run_steps(context, sky_steps(job.leaves, self.alpha, self.beta, self.resolution, folder,
                                                  scheduler=context.scene.radtr.scheduler))

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def finished(self, context, result):
        self._job.sky, paths = result
        seen = f"; {len(paths)} views in {bpy.path.abspath(self.out_dir)}" if paths else ""
        self.report({"INFO"}, f"RadTR: sky form factors of {len(self._job.sky.directions):,} dome points x "
                              f"{self._job.leaves.n:,} patches{seen}")
        return {"FINISHED"}
