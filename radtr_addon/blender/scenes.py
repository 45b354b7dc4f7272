"""Scenes to solve: bundled scenes (``scenes/*.py``, built by script), .blend and .obj files.

``open_scene(source)`` makes one the current Blender file; a bundled scene module is loaded by
path (it is not part of the engine) and builds itself with ``build(bpy)``.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

from ..errors import InputFileError, RadTRError

SCENES_DIR = Path(__file__).resolve().parents[2] / "scenes"


def bundled_scenes() -> list[str]:
    return sorted(p.stem for p in SCENES_DIR.glob("*.py") if not p.stem.startswith("_"))


def load_bundled(name: str):
    """The module of bundled scene ``name`` (loaded by path: it is not part of the engine)."""
    path = SCENES_DIR / f"{name}.py"
    if not path.is_file():
        raise RadTRError(f"no bundled scene '{name}' (have: {', '.join(bundled_scenes())})")
    spec = importlib.util.spec_from_file_location(f"radtr_scene_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


#: Blender's own importer for each file type: (operator, add-on that provides it, or None).
IMPORTERS = {
    ".ply": ("wm.ply_import", None), ".stl": ("wm.stl_import", None),
    ".gltf": ("import_scene.gltf", "io_scene_gltf2"), ".glb": ("import_scene.gltf", "io_scene_gltf2"),
    ".fbx": ("import_scene.fbx", "io_scene_fbx"),
    ".usd": ("wm.usd_import", None), ".usda": ("wm.usd_import", None), ".usdc": ("wm.usd_import", None),
    ".usdz": ("wm.usd_import", None), ".abc": ("wm.alembic_import", None),
}
#: File types whose materials carry no emission: light them with Light objects or the World.
NO_EMISSION = (".ply", ".stl", ".abc")


def readable_types() -> str:
    return ", ".join((".blend", ".obj", *IMPORTERS))


def open_scene(source: str) -> list[str]:
    """Make ``source`` the current Blender file; returns warnings from loading it.

    ``source`` is a .blend file, a scene file of a type Blender imports (``IMPORTERS``; .obj
    with RadTR's own checks), or the name of a bundled scene."""
    import bpy

    path = Path(source)
    suffix = path.suffix.lower()
    if suffix and suffix not in (".blend", ".obj", *IMPORTERS) and not (SCENES_DIR / f"{source}.py").is_file():
        raise InputFileError(f"{path}: unknown scene file type '{suffix}' (Blender reads {readable_types()})")
    if suffix and not path.is_file():
        raise InputFileError(f"{path}: no such file")
    if suffix == ".blend":
        try:
            bpy.ops.wm.open_mainfile(filepath=str(path))
        except RuntimeError as exc:
            reason = str(exc).strip().removeprefix("Error: ")
            raise InputFileError(f"{path}: not a .blend file Blender can read ({reason})") from None
        return []
    bpy.ops.wm.read_homefile(use_empty=True)
    if suffix == ".obj":
        from .objfile import load_obj

        return load_obj(path)
    if suffix in IMPORTERS:
        return import_file(path)
    load_bundled(source).build(bpy)
    return []


def import_file(path: Path) -> list[str]:
    """Import ``path`` into the current scene with Blender's importer for its type."""
    import addon_utils
    import bpy

    operator, addon = IMPORTERS[path.suffix.lower()]
    if addon and not addon_utils.check(addon)[1]:
        addon_utils.enable(addon, default_set=False)
    group, name = operator.split(".")
    before = set(bpy.data.objects)
    try:
        getattr(getattr(bpy.ops, group), name)(filepath=str(path))
    except RuntimeError as exc:
        reason = str(exc).strip().removeprefix("Error: ")
        raise InputFileError(f"{path}: Blender's {path.suffix.lower()} importer could not read it ({reason})") from None
    new = [o for o in bpy.data.objects if o not in before and o.type == "MESH" and len(o.data.polygons)]
    if not new:
        raise InputFileError(f"{path}: no mesh with faces in the file")
    if path.suffix.lower() in NO_EMISSION:
        return [f"{path.name}: {path.suffix.lower()} files carry no emission; add a Light or a World to light it"]
    return []
