"""Scenes in every format Blender's own importers read: the Cornell box written by Blender's
exporter in each format, read back by ``open_scene``, gives the same surface (area, triangles),
and the same emitted power where the format carries emission (glTF, USD, FBX)."""
import numpy as np
import pytest

from radtr_addon.blender.extract import extract, source_objects
from radtr_addon.blender.scenes import IMPORTERS, NO_EMISSION, open_scene
from radtr_addon.errors import InputFileError

#: Exporter operator and keyword arguments for each file type the test writes.
EXPORTERS = {
    ".ply": ("wm.ply_export", {}), ".stl": ("wm.stl_export", {}),
    ".glb": ("export_scene.gltf", {}), ".gltf": ("export_scene.gltf", {"export_format": "GLTF_SEPARATE"}),
    ".fbx": ("export_scene.fbx", {}), ".usdc": ("wm.usd_export", {}), ".abc": ("wm.alembic_export", {}),
}


def scene_of(bpy):
    ctx = bpy.context
    return extract(ctx.evaluated_depsgraph_get(), source_objects(ctx.scene, ctx.view_layer)).scene


def export(bpy, suffix, path):
    import addon_utils

    operator, kw = EXPORTERS[suffix]
    for addon in ("io_scene_gltf2", "io_scene_fbx"):
        addon_utils.enable(addon, default_set=False)
    group, name = operator.split(".")
    assert getattr(getattr(bpy.ops, group), name)(filepath=str(path), **kw) == {"FINISHED"}


@pytest.mark.parametrize("suffix", sorted(EXPORTERS))
def test_a_scene_file_reads_back_the_same_surface(cornell, tmp_path, suffix):
    bpy = cornell
    assert suffix in IMPORTERS
    box = scene_of(bpy)
    path = tmp_path / f"box{suffix}"
    export(bpy, suffix, path)
    warnings = open_scene(str(path))
    got = scene_of(bpy)
    assert got.n == box.n
    np.testing.assert_allclose(got.areas.sum(), box.areas.sum(), rtol=1e-5)
    if suffix in NO_EMISSION:
        assert "carry no emission" in warnings[0]
    else:
        np.testing.assert_allclose(got.emitted_power(), box.emitted_power(), rtol=1e-3)
        assert warnings == []


def test_unknown_or_missing_scene_files_are_named(blend, tmp_path):
    with pytest.raises(InputFileError, match=r"room.xyz: unknown scene file type '.xyz' \(Blender reads .blend, "):
        open_scene(str(tmp_path / "room.xyz"))
    with pytest.raises(InputFileError, match="room.glb: no such file"):
        open_scene(str(tmp_path / "room.glb"))
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"not a glb file")
    with pytest.raises(InputFileError, match="bad.glb: Blender's .glb importer could not read it"):
        open_scene(str(bad))
