"""Research tools on the last solve: a patch's view as an image, and the eye at a patch."""
import bpy
import numpy as np

from ..radtr_addon.views import id_colors, patch_view, view_from_patch
from .solve import running

VIEW_IMAGE = "RadTR Patch View"


def _last_job(op):
    job = running["last"]
    if job is None:
        op.report({"ERROR"}, "RadTR: solve first; the tools work on the last solve's patches")
    return job


class RADTR_OT_patch_view(bpy.types.Operator):
    """Write what a patch sees (hemicube or paraboloid, patch ids in colour code) into an Image"""

    bl_idname = "radtr.patch_view"
    bl_label = "Patch View Image"

    def execute(self, context):
        job = _last_job(self)
        if job is None:
            return {"CANCELLED"}
        s = context.scene.radtr
        if not 0 <= s.view_patch < job.leaves.n:
            self.report({"ERROR"}, f"RadTR: patch {s.view_patch} does not exist (0..{job.leaves.n - 1})")
            return {"CANCELLED"}
        ids = patch_view(job.leaves, s.view_patch, s.view_kind, 128)
        rgb = id_colors(ids)[::-1]                       # Blender images start at the bottom row
        h, w = rgb.shape[:2]
        image = bpy.data.images.get(VIEW_IMAGE)
        if image is None or tuple(image.size) != (w, h):
            if image is not None:
                bpy.data.images.remove(image)
            image = bpy.data.images.new(VIEW_IMAGE, w, h, float_buffer=True)
        rgba = np.ones((h, w, 4), dtype=np.float32)
        rgba[..., :3] = rgb
        image.pixels.foreach_set(rgba.ravel())
        image.update()
        self.report({"INFO"}, f"RadTR: {s.view_kind} view of {job.leaves.patch_label(s.view_patch)} in "
                              f"image '{VIEW_IMAGE}'")
        return {"FINISHED"}


class RADTR_OT_view_from_patch(bpy.types.Operator):
    """Put the viewport's eye at a patch, looking out along its normal"""

    bl_idname = "radtr.view_from_patch"
    bl_label = "View from Patch"

    @classmethod
    def poll(cls, context):
        return context.region_data is not None and running["last"] is not None

    def execute(self, context):
        job = running["last"]
        s = context.scene.radtr
        if not 0 <= s.view_patch < job.leaves.n:
            self.report({"ERROR"}, f"RadTR: patch {s.view_patch} does not exist (0..{job.leaves.n - 1})")
            return {"CANCELLED"}
        eye, q = view_from_patch(job.leaves, s.view_patch)
        rv3d = context.region_data
        rv3d.view_perspective = "PERSP"
        rv3d.view_rotation = q
        rv3d.view_distance = 1e-4
        rv3d.view_location = eye
        return {"FINISHED"}


class RADTR_OT_load_vector(bpy.types.Operator):
    """Load a per-patch radiosity (shown as it is) or emission (solved, then shown) from a file
    (.npz, .mat, .dat, .csv) onto the last solve's patches; a file that does not fit changes nothing"""

    bl_idname = "radtr.load_vector"
    bl_label = "Load Patch Vector"
    bl_options = {"REGISTER", "UNDO"}

    filepath: bpy.props.StringProperty(subtype="FILE_PATH")
    kind: bpy.props.EnumProperty(items=[("radiosity", "Radiosity", "Show B as it is"),
                                        ("emission", "Emission", "Solve with this E and show B")])

    def execute(self, context):
        from ..radtr_addon.blender.flashlight import LiveMeshes
        from ..radtr_addon.blender.sequence import solve_with_emission
        from ..radtr_addon.errors import RadTRError
        from ..radtr_addon.exchange import load_vector

        job = _last_job(self)
        if job is None:
            return {"CANCELLED"}
        try:
            v = load_vector(bpy.path.abspath(self.filepath), job.leaves.n)
            B = v if self.kind == "radiosity" else solve_with_emission(job, v)
        except RadTRError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        LiveMeshes(job.objects, job.leaves).write(B)
        self.report({"INFO"}, f"RadTR: {self.kind} of {job.leaves.n:,} patches loaded from {self.filepath}")
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


class RADTR_OT_toggle_emission(bpy.types.Operator):
    """Click patches to switch their emission on or off and see the light solved again (Esc or right click ends)"""

    bl_idname = "radtr.toggle_emission"
    bl_label = "Toggle Patch Emission"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return running["last"] is not None and context.area is not None and context.area.type == "VIEW_3D"

    def invoke(self, context, event):
        self.emission = running["last"].leaves.emission.copy()
        context.window_manager.modal_handler_add(self)
        context.area.header_text_set("RadTR: click a patch to switch its emission; Esc or right click ends")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        from ..radtr_addon.blender.sequence import toggle_patch
        from .flashlight import mouse_ray

        if event.type in ("ESC", "RIGHTMOUSE"):
            context.area.header_text_set(None)
            return {"FINISHED"}
        if event.type != "LEFTMOUSE" or event.value != "PRESS":
            return {"PASS_THROUGH"}
        origin, direction = mouse_ray(context, event)
        i, self.emission = toggle_patch(running["last"], origin, direction, self.emission)
        if i >= 0:
            self.report({"INFO"}, f"RadTR: {running['last'].leaves.patch_label(i)} "
                                  f"{'on' if self.emission[i].max() > 0 else 'off'}")
        return {"RUNNING_MODAL"}
