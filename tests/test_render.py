"""Pictures a user can read: a closed room rendered without a camera is seen from outside
as a dollhouse (walls seen from behind are see-through), and ``--camera`` names the camera."""
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT

from radtr_addon.blender.pipeline import solve
from radtr_addon.blender.render import render_png
from radtr_addon.errors import SceneError
from radtr_addon.settings import Settings

FAST = Settings(max_area=0.01, method="embree", rays=64, tolerance=1e-2)


def front_wall(bpy):
    """A white wall over the Cornell box's open side (y = 0), facing into the box."""
    from scenes._common import material

    mesh = bpy.data.meshes.new("front_wall")
    mesh.from_pydata([(0, 0, 0), (0, 0, 0.5592), (0.556, 0, 0.5592), (0.556, 0, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material(bpy, "front", (0.7, 0.7, 0.7)))
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("front_wall", mesh))


def picture(bpy, path) -> np.ndarray:
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 48
    render_png(scene, str(path))
    image = bpy.data.images.load(str(path))
    rgba = np.array(image.pixels[:]).reshape(48, 48, 4)
    bpy.data.images.remove(image)
    return rgba[..., :3]


def sides(rgb) -> tuple[float, float]:
    """Red over green in the left third and in the right third of the picture."""
    left, right = rgb[:, :16].mean(axis=(0, 1)), rgb[:, 32:].mean(axis=(0, 1))
    return left[0] / left[1], right[0] / right[1]


def test_closed_room_without_camera_is_seen_inside(cornell, tmp_path):
    bpy = cornell
    bpy.data.objects.remove(bpy.data.objects["camera"])
    solve(bpy.context, FAST, log=lambda *_: None)
    open_left, open_right = sides(picture(bpy, tmp_path / "open.png"))
    assert (open_left > 2) != (open_right > 2)                 # the red wall on one side, the green on the other
    bpy.ops.radtr.clear()
    front_wall(bpy)
    solve(bpy.context, FAST, log=lambda *_: None)
    closed = picture(bpy, tmp_path / "closed.png")
    left, right = sides(closed)
    assert (left > 2, right > 2) == (open_left > 2, open_right > 2)    # the same walls, through the front one
    assert closed.mean() > 0.05


def test_render_through_a_named_camera(cornell, tmp_path):
    bpy = cornell
    solve(bpy.context, FAST, log=lambda *_: None)
    data = bpy.data.cameras.new("side")
    side = bpy.data.objects.new("side", data)
    bpy.context.scene.collection.objects.link(side)
    missing = "no camera or saved view 'nope' in scene .* \\(cameras: camera, side; saved views: none\\)"
    with pytest.raises(SceneError, match=missing):
        render_png(bpy.context.scene, str(tmp_path / "x.png"), camera="nope")
    render_png(bpy.context.scene, str(tmp_path / "side.png"), camera="side")
    assert bpy.context.scene.camera.name == "camera"           # the scene's own camera again
    assert (tmp_path / "side.png").is_file()


def cli_solve(scene, *flags):
    return subprocess.run([sys.executable, "-m", "radtr_addon", "solve", str(scene), "--max-area", "0.05",
                           "--method", "embree", "--rays", "16", *flags], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)


def test_cli_checks_the_picture_flags_before_solving(tmp_path):
    run = cli_solve("cornell_box", "--render", str(tmp_path / "r.png"), "--camera", "nope")
    assert run.returncode == 2 and "no camera or saved view 'nope'" in run.stderr
    assert "patches" not in run.stdout                          # refused before the solve
    run = cli_solve("cornell_box", "--render", str(tmp_path / "r.jpg"))
    assert run.returncode == 2 and "the picture is written as PNG; name it .png" in run.stderr
    run = cli_solve("cornell_box", "--camera", "camera")
    assert run.returncode == 2 and "--camera camera needs --render" in run.stderr


def test_cli_renders_through_a_saved_view_of_a_blend_file(cornell, tmp_path):
    from types import SimpleNamespace

    from radtr_addon.blender.viewpoints import store_view

    bpy = cornell
    cam = bpy.data.objects["camera"]
    store_view(bpy.context.scene.radtr, SimpleNamespace(view_location=tuple(cam.matrix_world.translation),
                                                        view_rotation=tuple(cam.matrix_world.to_quaternion()),
                                                        view_distance=0.0), "front")
    bpy.context.scene.render.resolution_x = bpy.context.scene.render.resolution_y = 32
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "box.blend"))
    run = cli_solve(tmp_path / "box.blend", "--render", str(tmp_path / "front.png"), "--camera", "front")
    assert run.returncode == 0, run.stderr[-2000:]
    assert (tmp_path / "front.png").is_file()
