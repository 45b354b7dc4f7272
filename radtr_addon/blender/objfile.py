"""Load Wavefront OBJ files through Blender's own importer, with RadTR's checks around it.

Before importing, the file is scanned for faces the importer would drop silently (fewer than
three corners, index 0, indices outside the vertices read so far); each is reported with
its line as a warning, and the import goes on without them (documented repair). A file
left with no valid face is refused. Missing material libraries are reported; their faces
get Blender's default material.

OBJ has no standard emission besides ``Ke``. Files from the Embree/tinyobjloader Cornell box
put the light's radiance in ``Ka`` (ambient), which Blender's importer ignores. Rule: a
material with ``Ka`` > 0 and no ``Ke`` becomes an emitter of radiance ``Ka`` (Blender
Emission Strength max(Ka), Color Ka / max(Ka)), with a warning naming it.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..errors import InputFileError


def scan_obj(path: Path) -> tuple[list[str], list[str]]:
    """(problems with line numbers, material library names) of the OBJ file at ``path``."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except FileNotFoundError:
        raise InputFileError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputFileError(f"{path}: cannot be read as a text OBJ file ({exc})") from None
    counts = {"v": 0, "vt": 0, "vn": 0}
    problems, libs = [], []
    for lineno, line in enumerate(text.splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        key = parts[0]
        if key in counts:
            counts[key] += 1
            if key == "v" and not _finite(parts[1:4]):
                raise InputFileError(f"{path.name}:{lineno}: vertex {counts['v']} has coordinates "
                                     f"{' '.join(parts[1:4])}; every coordinate must be a finite number")
        elif key == "mtllib":
            libs += parts[1:]
        elif key == "f":
            problem = _face_problem(parts[1:], counts)
            if problem:
                problems.append(f"{path.name}:{lineno}: {problem}; face skipped")
    return problems, libs


def _finite(values) -> bool:
    try:
        return len(values) > 0 and all(math.isfinite(float(x)) for x in values)
    except ValueError:
        return False


def _face_problem(corners, counts) -> str | None:
    if len(corners) < 3:
        return f"face has {len(corners)} corner(s), a face needs 3 or more"
    for corner in corners:
        for value, kind in zip(corner.split("/"), ("v", "vt", "vn")):
            if not value:
                continue
            try:
                index = int(value)
            except ValueError:
                return f"face index '{value}' is not a number"
            if index == 0:
                return "face index 0 (OBJ indices start at 1)"
            resolved = index if index > 0 else counts[kind] + 1 + index
            if not 1 <= resolved <= counts[kind]:
                return f"face index {index} outside the {counts[kind]} '{kind}' entries read so far"
    return None


def read_mtl(path: Path, warnings: list[str]) -> dict[str, dict[str, tuple[float, ...]]]:
    """{material: {key: values}} of an MTL file (only the numeric keys RadTR uses). A Kd that is
    not three finite numbers in 0..1 is a warning (Blender uses its default); a Ke that is NaN,
    infinite or negative is refused."""
    materials: dict[str, dict] = {}
    name = current = None
    for lineno, line in enumerate(path.read_text(encoding="utf-8-sig", errors="replace").splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        if parts[0] == "newmtl" and len(parts) > 1:
            name = " ".join(parts[1:])
            current = materials.setdefault(name, {})
        elif current is not None and parts[0] in ("Ka", "Kd", "Ke"):
            where = f"{path.name}:{lineno}: material '{name}': {parts[0]} {' '.join(parts[1:4])}"
            if not _finite(parts[1:4]):
                if parts[0] == "Ke":
                    raise InputFileError(f"{where} is not a finite emission")
                warnings.append(f"{where} is not three numbers; Blender's default is used")
                continue
            values = tuple(float(x) for x in parts[1:4])
            if parts[0] == "Ke" and min(values) < 0:
                raise InputFileError(f"{where} is negative; emission must be 0 or more")
            if parts[0] == "Kd" and not 0 <= min(values) <= max(values) <= 1:
                warnings.append(f"{where} is outside 0..1; reflectances are clamped to 0..Max Reflectance")
            current[parts[0]] = values
    return materials


def load_obj(path: str | Path) -> list[str]:
    """Import ``path`` into the current scene; returns the warnings to show the user."""
    import bpy

    path = Path(path)
    problems, libs = scan_obj(path)
    warnings = list(problems)
    mtl = {}
    for lib in libs:
        lib_path = path.parent / lib
        if lib_path.is_file():
            mtl.update(read_mtl(lib_path, warnings))
        else:
            warnings.append(f"{path.name}: material library '{lib}' not found; "
                            f"its faces use Blender's default material")
    before = set(bpy.data.objects)
    bpy.ops.wm.obj_import(filepath=str(path))
    new = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    if not any(len(o.data.polygons) for o in new):
        first = f" (first problem: {problems[0]})" if problems else ""
        raise InputFileError(f"{path}: no valid faces could be read{first}")
    warnings += _ambient_emitters(new, mtl)
    return warnings


def _ambient_emitters(objects, mtl) -> list[str]:
    warnings = []
    seen = set()
    for obj in objects:
        for slot in obj.material_slots:
            mat = slot.material
            if mat is None or mat.name in seen:
                continue
            seen.add(mat.name)
            entry = mtl.get(mat.name, {})
            ka, ke = entry.get("Ka", (0, 0, 0)), entry.get("Ke")
            if ke or max(ka) <= 0:
                continue
            bsdf = mat.node_tree.nodes.get("Principled BSDF") if mat.node_tree else None
            if bsdf is None:
                continue
            strength = max(ka)
            bsdf.inputs["Emission Color"].default_value = (*(c / strength for c in ka), 1.0)
            bsdf.inputs["Emission Strength"].default_value = strength
            warnings.append(f"material '{mat.name}': Ka {ka} taken as emitted radiance "
                            f"(OBJ rule: Ka > 0 without Ke makes an emitter)")
    return warnings
