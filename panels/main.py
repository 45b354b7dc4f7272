"""RadTR's N-panel: Patches and Solve with a live readout (residual, energy) of a running
solve, and sub-panels for the form factors, the flashlight, lighting scenarios and views."""
import bpy

from ..operators.session import running
from ..radtr_addon.formfactors.methods import LEVELLED_SPLITS
from ..radtr_addon.settings import Settings


class _RadTRPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "RadTR"


class _SubPanel(_RadTRPanel):
    bl_parent_id = "RADTR_PT_main"


class RADTR_PT_main(_RadTRPanel, bpy.types.Panel):
    bl_label = "RadTR"
    bl_idname = "RADTR_PT_main"

    def draw(self, context):
        s = context.scene.radtr
        col = self.layout.column()
        col.label(text="Patches")
        col.prop(s, "max_area")
        col.prop(s, "levels")
        col.operator("radtr.subdivide", icon="MOD_SUBSURF")
        col.separator()
        col.label(text="Solve")
        col.prop(s, "solver")
        if s.solver == "shooting":
            col.prop(s, "ambient")
        elif s.solver == "user":
            col.prop(s, "user_solver")
        col.prop(s, "quality" if s.solver == "hierarchical" else "precision")
        col.prop(s, "tolerance")
        col.prop(s, "max_iterations")
        col.prop(s, "gather_rays")
        if s.gather_rays < 0:                              # auto: say what it resolves to
            rays = Settings.of(s).vertex_gather
            col.label(text=f"Auto: {rays:,} rays a vertex" if rays else "Auto: patch means", icon="INFO")
        col.prop(s, "sky")
        if s.sky != "none":
            col.prop(s, "sky_radiance")
            col.prop(s, "sky_step")
            col.prop(s, "sky_altitude_step")
            col.prop(s, "sky_resolution")
        col.prop(s, "max_reflectance")
        col.prop(s, "cache_mb")
        col.prop(s, "scheduler")
        col.prop(s, "mode", expand=True)
        row = col.row(align=True)
        row.operator("radtr.solve", icon="LIGHT_SUN")
        row.operator("radtr.resume", icon="PLAY", text="Continue")
        col.operator("radtr.export_gltf", icon="EXPORT")
        RADTR_PT_main.draw_readout(col)

    @staticmethod
    def draw_readout(col):
        job = running["job"]
        if job is None:
            return
        solver = job.solver
        box = col.box()
        box.label(text=solver.phase)
        box.label(text=f"Residual {solver.residual:.2e} of emitted (stop at {solver.tol:g})")
        e = solver.energy()
        box.label(text=f"Absorbed {e['absorbed']:.1%}, escaped {e['escaped'] + e['blocked']:.1%}, "
                       f"unshot {e['unshot']:.1%}")


class RADTR_PT_form_factors(_SubPanel, bpy.types.Panel):
    """How the uniform solvers' form factors are computed (the hierarchical one makes its own)."""

    bl_label = "Form Factors"
    bl_idname = "RADTR_PT_form_factors"

    @classmethod
    def poll(cls, context):
        return context.scene.radtr.solver != "hierarchical"

    def draw(self, context):
        s = context.scene.radtr
        col = self.layout.column()
        col.prop(s, "method")
        col.prop(s, "rays" if s.method == "embree" else "resolution")
        if s.method == "hemicube":
            col.prop(s, "rotate")
        elif s.method == "paraboloid":
            col.prop(s, "split")
            if s.split in LEVELLED_SPLITS:
                col.prop(s, "split_level")


class RADTR_PT_flashlight(_SubPanel, bpy.types.Panel):
    bl_label = "Flashlight"
    bl_idname = "RADTR_PT_flashlight"

    def draw(self, context):
        s = context.scene.radtr
        col = self.layout.column()
        col.prop(s, "lowrank_level")
        col.prop(s, "lowrank_refine")
        col.prop(s, "lowrank_backend")
        if s.lowrank_backend == "user":
            col.prop(s, "lowrank_user")
        col.operator("radtr.flashlight", icon="LIGHT_SPOT")


class RADTR_PT_scenarios(_SubPanel, bpy.types.Panel):
    """Stored lighting scenarios and their weights."""

    bl_label = "Lighting Scenarios"
    bl_idname = "RADTR_PT_scenarios"

    def draw(self, context):
        s = context.scene.radtr
        col = self.layout.column()
        for i, item in enumerate(s.scenarios):
            row = col.row(align=True)
            row.prop(item, "name", text="")
            row.prop(item, "weight", text="", slider=True)
            row.operator("radtr.scenario_remove", text="", icon="X").index = i
        col.operator("radtr.scenario_add", icon="ADD")


class RADTR_PT_views(_SubPanel, bpy.types.Panel):
    bl_label = "Views"
    bl_idname = "RADTR_PT_views"

    def draw(self, context):
        s = context.scene.radtr
        col = self.layout.column()
        col.prop(s, "display")
        col.prop(s, "exposure")
        col.prop(s, "view_patch")
        col.prop(s, "view_kind")
        row = col.row(align=True)
        row.operator("radtr.patch_view", icon="IMAGE_DATA")
        row.operator("radtr.view_from_patch", icon="VIEW_CAMERA")
        col.operator("radtr.pick_view", icon="RESTRICT_SELECT_OFF")
        if context.region_data is not None:
            from ..radtr_addon.blender.viewpoints import info_line

            col.label(text=info_line(context.region_data))
        for i, view in enumerate(s.views):
            row = col.row(align=True)
            row.operator("radtr.view_recall", text=view.name, icon="HIDE_OFF").index = i
            row.operator("radtr.view_remove", text="", icon="X").index = i
        col.operator("radtr.view_store", icon="ADD")
        row = col.row(align=True)
        row.operator("radtr.capture", icon="RENDER_STILL").kind = "RENDER"
        row.operator("radtr.capture", text="Viewport", icon="RESTRICT_VIEW_OFF").kind = "VIEWPORT"
        col.operator("radtr.clear", icon="TRASH")


class RADTR_PT_research(_SubPanel, bpy.types.Panel):
    """The research workbench on the last solve: matrices out, vectors in, sequences, the sky."""

    bl_label = "Research"
    bl_idname = "RADTR_PT_research"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        col = self.layout.column()
        col.operator("radtr.export", icon="EXPORT")
        col.operator("radtr.sky_factors", icon="WORLD")
        col.operator("radtr.load_vector", icon="FILE_FOLDER")
        col.operator("radtr.sequence", icon="RENDER_ANIMATION")
        col.operator("radtr.watch", icon="HIDE_OFF")
        col.operator("radtr.toggle_emission", icon="RESTRICT_SELECT_OFF")
