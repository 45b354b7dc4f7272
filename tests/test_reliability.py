"""Bad and extreme input: each case gets a clear error naming what is wrong, and a failure
leaves the Blender file as it was (object and mesh names, meshes' data and modifiers)."""
from types import SimpleNamespace

import numpy as np
import pytest

from radtr_addon.blender.pipeline import Settings, solve
from radtr_addon.errors import SceneError

FAST = dict(max_area=0.01, method="embree", rays=16, tolerance=1e-2)


def state(bpy):
    """Everything a failed solve must leave as it was."""
    objects = sorted((o.name, o.data.name if o.data else None, len(o.modifiers), o.hide_get(), o.hide_render)
                     for o in bpy.data.objects)
    meshes = {}
    for m in bpy.data.meshes:
        co = np.empty(len(m.vertices) * 3)
        m.vertices.foreach_get("co", co)
        meshes[m.name] = (len(m.polygons), co.round(6).tobytes(), sorted(a.name for a in m.attributes))
    return objects, meshes


def quiet(*_):
    pass


# -- a Replace solve that fails halfway -------------------------------------------------------

def test_replace_with_a_zero_scale_object_is_refused_before_any_work(cornell):
    bpy = cornell
    bpy.data.objects["short_block"].scale = (1, 1, 0)
    before = state(bpy)
    with pytest.raises(SceneError, match="object 'short_block' has a zero scale along an axis"):
        solve(bpy.context, Settings(mode="REPLACE", **FAST), log=quiet)
    assert state(bpy) == before


def test_replace_failing_while_writing_changes_nothing(cornell, monkeypatch):
    from radtr_addon.blender import write

    bpy = cornell
    bpy.data.objects["floor"].modifiers.new("bevel", "BEVEL")
    before = state(bpy)
    calls = []

    def to_local(mesh, matrix):
        calls.append(mesh.name)
        if len(calls) == 4:
            raise ValueError("disk full")
        real_to_local(mesh, matrix)

    real_to_local = write._to_local
    monkeypatch.setattr(write, "_to_local", to_local)
    with pytest.raises(ValueError, match="disk full"):
        solve(bpy.context, Settings(mode="REPLACE", **FAST), log=quiet)
    assert len(calls) == 4 and state(bpy) == before


def test_replace_that_succeeds_keeps_each_object_in_place(cornell):
    bpy = cornell
    floor = bpy.data.objects["floor"]
    floor.scale = (2, 1, 1)
    lo = np.array([floor.matrix_world @ v.co for v in floor.data.vertices]).min(axis=0)
    solve(bpy.context, Settings(mode="REPLACE", **FAST), log=quiet)
    assert floor.data.name == "floor_radtr"
    after = np.array([floor.matrix_world @ v.co for v in floor.data.vertices]).min(axis=0)
    np.testing.assert_allclose(after, lo, atol=1e-5)


def test_modal_solve_that_raises_is_cleared_and_reported(addon, cornell):
    import radtr.operators.solve as op

    reports = []
    wm = SimpleNamespace(event_timer_remove=quiet, progress_end=quiet, progress_update=quiet)
    context = SimpleNamespace(window_manager=wm, workspace=SimpleNamespace(status_text_set=quiet),
                              screen=SimpleNamespace(areas=[]))

    def advance(seconds):
        raise ZeroDivisionError("division by zero")

    op.running["job"] = SimpleNamespace(advance=advance)
    modal = SimpleNamespace(_timer=None, report=lambda kind, msg: reports.append((kind, msg)),
                            _end=lambda ctx: op._ModalSolve._end(modal, ctx))
    assert op._ModalSolve.modal(modal, context, SimpleNamespace(type="TIMER")) == {"CANCELLED"}
    assert op.running["job"] is None
    assert reports == [({"ERROR"}, reports[0][1])]
    assert reports[0][1].startswith("unexpected error: ZeroDivisionError: division by zero (test_reliability.py:")
    assert op.RADTR_OT_solve.poll(cornell.context)
