"""Saved viewpoints: a view's eye and axes by closed form, stored in the .blend and recalled,
rendered through (the same picture as a camera at that pose), and captured to PNG."""
from types import SimpleNamespace

import numpy as np
import pytest

from radtr_addon.blender.pipeline import solve
from radtr_addon.blender.viewpoints import eye_axes, recall_view, store_view
from radtr_addon.settings import Settings

FAST = Settings(max_area=0.02, method="embree", rays=32, tolerance=1e-2)


def test_eye_and_axes_of_a_view():
    eye, forward, right = eye_axes((1, 2, 3), (1, 0, 0, 0), 5.0)
    np.testing.assert_allclose([eye, forward, right], [[1, 2, 8], [0, 0, -1], [1, 0, 0]], atol=1e-12)
    half = np.sqrt(0.5)                                       # a quarter turn about +X: looking along +Y
    eye, forward, right = eye_axes((0, 0, 0), (half, half, 0, 0), 2.0)
    np.testing.assert_allclose([eye, forward, right], [[0, -2, 0], [0, 1, 0], [1, 0, 0]], atol=1e-12)


def test_views_are_kept_in_the_blend_and_recalled(blend, tmp_path):
    bpy = blend
    s = bpy.context.scene.radtr
    rv3d = SimpleNamespace(view_location=(1.0, 2.0, 3.0), view_rotation=(0.5, 0.5, 0.5, 0.5), view_distance=4.0,
                           view_perspective="ORTHO")
    store_view(s, rv3d, "hall", lens=35.0)
    assert store_view(s, rv3d, "hall").name == "hall 2"
    path = tmp_path / "views.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    views = bpy.context.scene.radtr.views
    assert [v.name for v in views] == ["hall", "hall 2"] and views[0].lens == pytest.approx(35.0)
    target = SimpleNamespace()
    recall_view(views[0], target)
    assert target.view_perspective == "PERSP" and target.view_distance == pytest.approx(4.0)
    np.testing.assert_allclose(target.view_rotation, (0.5, 0.5, 0.5, 0.5))


def pixels(bpy, path):
    image = bpy.data.images.load(str(path))
    try:
        return np.array(image.pixels[:])
    finally:
        bpy.data.images.remove(image)


def test_a_saved_view_renders_what_a_camera_there_sees(cornell, tmp_path):
    from radtr_addon.blender.render import render_png

    bpy = cornell
    solve(bpy.context, FAST, log=lambda *_: None)
    scene, cam = bpy.context.scene, bpy.data.objects["camera"]
    scene.render.resolution_x = scene.render.resolution_y = 40
    cam.data.sensor_width, cam.data.sensor_fit, cam.data.lens = 36.0, "AUTO", 30.0
    rotation = cam.matrix_world.to_quaternion()
    store_view(scene.radtr, SimpleNamespace(view_location=tuple(cam.matrix_world.translation),
                                            view_rotation=tuple(rotation), view_distance=0.0), "front", lens=30.0)
    render_png(scene, str(tmp_path / "camera.png"))
    render_png(scene, str(tmp_path / "view.png"), camera="front")
    assert scene.camera == cam and "RadTR view front" not in bpy.data.objects      # the temporary camera is gone
    through_camera, through_view = pixels(bpy, tmp_path / "camera.png"), pixels(bpy, tmp_path / "view.png")
    assert through_camera.mean() > 0.05
    assert np.abs(through_camera - through_view).max() < 2 / 255


def test_capture_renders_a_still_and_an_animation(cornell, tmp_path):
    bpy = cornell
    solve(bpy.context, FAST, log=lambda *_: None)
    scene, cam = bpy.context.scene, bpy.data.objects["camera"]
    scene.render.resolution_x = scene.render.resolution_y = 24
    assert bpy.ops.radtr.capture(filepath=str(tmp_path / "still.png")) == {"FINISHED"}
    assert (tmp_path / "still.png").is_file()
    scene.frame_start, scene.frame_end = 1, 2
    cam.keyframe_insert("location", frame=1)
    cam.location.x += 0.2
    cam.keyframe_insert("location", frame=2)
    assert bpy.ops.radtr.capture(filepath=str(tmp_path / "fly_"), animation=True) == {"FINISHED"}
    frames = sorted(tmp_path.glob("fly_*.png"))
    assert [f.name for f in frames] == ["fly_0001.png", "fly_0002.png"]
    assert np.abs(pixels(bpy, frames[0]) - pixels(bpy, frames[1])).max() > 0.1     # the camera moved
