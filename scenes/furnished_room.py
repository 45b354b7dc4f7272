"""A furnished room: a closed box with a window, a ceiling panel light and furniture.

Metres, z up. The room is x 0..5, y 0..4, z 0..2.7 (inner faces; zero-thickness walls, every
normal facing into the room). Objects and materials (Principled BSDF, roughness 1, specular 0;
RGB reflectance in brackets):

- ``Floor`` (z = 0, wood 0.4 0.3 0.2), ``Ceiling`` (z = 2.7, 0.75 0.75 0.75), ``Wall_North``
  (y = 4), ``Wall_South`` (y = 0), ``Wall_West`` (x = 0), one quad each, and ``Wall_East``
  (x = 5), eight quads around a window opening y 1.2..2.6, z 0.8..2.1 (a hole in the mesh);
  walls off-white 0.7 0.7 0.68.
- ``Table`` (wood 0.35 0.22 0.12): a top 1.2 x 0.8 x 0.04 m over x 1.4..2.6, y 1.7..2.5,
  z 0.71..0.75, on four 5 x 5 cm legs z 0..0.71 inset 5 cm from its corners.
- ``Sofa`` (fabric 0.15 0.25 0.45): a seat block x 2.6..4.4, y 3.1..3.95, z 0..0.42 and a
  backrest block x 2.6..4.4, y 3.75..3.95, z 0.42..0.85 on top of it.
- ``Low_Box`` (0.3 0.4 0.25): x 3.5..4.3, y 2.2..2.7, z 0..0.4, in front of the sofa.
- ``Cabinet`` (0.55 0.5 0.42): x 1.0..2.0, y 3.4..3.9, z 0..2.0.
- ``Lamp``: one quad 0.6 x 0.6 m, x 2.2..2.8, y 1.7..2.3, at z = 2.69, normal down; its
  material ``Lamp`` has Base Color 0.8 and emission radiance 20 x (1, 0.93, 0.8) W/(m^2 sr)
  (Emission Strength 20). Backface Culling is off, so it emits from both sides, as Cycles
  renders a mesh light: 2 x 0.36 m^2 x pi x 20 = 45 W per unit of colour.
- ``Sun``: a sun light of strength 10 W/m^2, angle 0.5 degrees, elevation 30 degrees, shining
  through the window towards -x (15 degrees towards -y): a sunlit parallelogram on the floor
  within x 1.5..3.7, y 0.3..2.2. The World ``Sky`` is a Background of colour 0.4 0.6 1.0, strength 1.
- ``Camera``: at (0.35, 0.35, 1.6), 18 mm lens, 36 mm film, 640 x 480, looking at
  (3.4, 2.6, 1.05): it sees the table, the sofa, the cabinet, the low box, the lamp and the window.

Contact cases (what the issue's leaks and hot spots are about):

- resting on the floor, gap 0 cm (bottom z = 0 exactly): the table's legs, the sofa seat, the
  low box, the cabinet;
- resting on another object, gap 0 cm: the table top on the legs (z = 0.71), the backrest on
  the seat (z = 0.42);
- the lamp 1 cm below the ceiling (z = 2.69 against 2.70), lighting the ceiling with its back;
- the cabinet's back 10 cm from the north wall (y = 3.9 against 4.0);
- the sofa's back 5 cm from the north wall (y = 3.95 against 4.0).

Faces that lie on another surface are left out (box bottoms on the floor, the legs' tops under
the table top, the backrest's bottom on the seat); all boxes are otherwise closed with normals
facing out. 56 quads, 112 input triangles.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

_spec = importlib.util.spec_from_file_location("radtr_scene_common", Path(__file__).with_name("_common.py"))
common = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(common)

ROOM = (5.0, 4.0, 2.7)
WINDOW = (1.2, 2.6, 0.8, 2.1)          # y0, y1, z0, z1 of the opening in the east wall (x = 5)
LAMP = (2.2, 2.8, 1.7, 2.3, 2.69)      # x0, x1, y0, y1, z
TABLE_TOP = ((1.4, 1.7, 0.71), (2.6, 2.5, 0.75))
LEG = 0.05
LEG_INSET = 0.05
SOFA_SEAT = ((2.6, 3.1, 0.0), (4.4, 3.95, 0.42))
SOFA_BACK = ((2.6, 3.75, 0.42), (4.4, 3.95, 0.85))
LOW_BOX = ((3.5, 2.2, 0.0), (4.3, 2.7, 0.4))
CABINET = ((1.0, 3.4, 0.0), (2.0, 3.9, 2.0))
CAMERA = ((0.35, 0.35, 1.6), (3.4, 2.6, 1.05))   # location, target
SUN_ELEVATION, SUN_AZIMUTH = 30.0, 15.0          # degrees; rays travel -x, turned towards -y
#: Points in the open (not inside furniture), for checks.
FREE_POINTS = ((2.5, 2.0, 1.35), (0.35, 0.35, 1.6), (4.5, 0.6, 2.0), (0.5, 2.0, 0.3), (3.4, 1.0, 0.2))

MATERIALS = {  # name: (RGB reflectance, emission strength, emission colour)
    "Wall": ((0.7, 0.7, 0.68), 0.0, None),
    "Floor": ((0.4, 0.3, 0.2), 0.0, None),
    "Ceiling": ((0.75, 0.75, 0.75), 0.0, None),
    "Table": ((0.35, 0.22, 0.12), 0.0, None),
    "Sofa": ((0.15, 0.25, 0.45), 0.0, None),
    "Low_Box": ((0.3, 0.4, 0.25), 0.0, None),
    "Cabinet": ((0.55, 0.5, 0.42), 0.0, None),
    "Lamp": ((0.8, 0.8, 0.8), 20.0, (1.0, 0.93, 0.8)),
}

# Box faces as corner indices into the 8 corners (bit 0: x, bit 1: y, bit 2: z), wound outwards.
_BOX_FACES = {
    "-z": (0, 2, 3, 1), "+z": (4, 5, 7, 6), "-y": (0, 1, 5, 4),
    "+y": (2, 6, 7, 3), "-x": (0, 4, 6, 2), "+x": (1, 3, 7, 5),
}


def box(lo, hi, skip=()):
    """(8, 3) corners and the quads of an axis-aligned box, normals out, faces in ``skip`` left out."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    corners = np.array([[(hi if i & 1 else lo)[0], (hi if i & 2 else lo)[1], (hi if i & 4 else lo)[2]]
                        for i in range(8)])
    return corners, [f for k, f in _BOX_FACES.items() if k not in skip]


def _quad_x(x, y0, y1, z0, z1, facing):
    """A quad in the plane x = const, normal towards ``facing`` (+1: +x)."""
    q = [(x, y0, z0), (x, y1, z0), (x, y1, z1), (x, y0, z1)]
    return q if facing > 0 else q[::-1]


def room_surfaces():
    """name: (material, list of quads) for the room's shell, normals facing in."""
    w, d, h = ROOM
    y0, y1, z0, z1 = WINDOW
    ys, zs = (0.0, y0, y1, d), (0.0, z0, z1, h)
    east = [_quad_x(w, ys[i], ys[i + 1], zs[j], zs[j + 1], -1)
            for i in range(3) for j in range(3) if (i, j) != (1, 1)]
    return {
        "Floor": ("Floor", [[(0, 0, 0), (w, 0, 0), (w, d, 0), (0, d, 0)]]),
        "Ceiling": ("Ceiling", [[(0, 0, h), (0, d, h), (w, d, h), (w, 0, h)]]),
        "Wall_North": ("Wall", [[(0, d, 0), (w, d, 0), (w, d, h), (0, d, h)]]),
        "Wall_South": ("Wall", [[(0, 0, 0), (0, 0, h), (w, 0, h), (w, 0, 0)]]),
        "Wall_West": ("Wall", [_quad_x(0.0, 0.0, d, 0.0, h, +1)]),
        "Wall_East": ("Wall", east),
    }


def furniture():
    """name: (material, [(corners, quads), ...]) for the furniture boxes."""
    (tx0, ty0, tz0), (tx1, ty1, _) = TABLE_TOP
    legs = []
    for x in (tx0 + LEG_INSET, tx1 - LEG_INSET - LEG):
        for y in (ty0 + LEG_INSET, ty1 - LEG_INSET - LEG):
            legs.append(box((x, y, 0.0), (x + LEG, y + LEG, tz0), skip=("-z", "+z")))
    return {
        "Table": ("Table", [box(*TABLE_TOP), *legs]),
        "Sofa": ("Sofa", [box(*SOFA_SEAT, skip=("-z",)), box(*SOFA_BACK, skip=("-z",))]),
        "Low_Box": ("Low_Box", [box(*LOW_BOX, skip=("-z",))]),
        "Cabinet": ("Cabinet", [box(*CABINET, skip=("-z",))]),
    }


def lamp_quad():
    x0, x1, y0, y1, z = LAMP
    return [(x0, y0, z), (x0, y1, z), (x1, y1, z), (x1, y0, z)]   # normal -z


def sun_direction() -> np.ndarray:
    """Unit direction the sun's light travels in."""
    el, az = math.radians(SUN_ELEVATION), math.radians(SUN_AZIMUTH)
    return np.array([-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), -math.sin(el)])


def build(bpy):
    """Add the furnished room (objects, materials, sun, sky, camera) to the current scene; return it."""
    scene = bpy.context.scene
    mats = {name: common.material(bpy, name, *spec) for name, spec in MATERIALS.items()}
    for name, (mat, quads) in room_surfaces().items():
        _add_mesh(bpy, scene, name, np.array(quads, float).reshape(-1, 3),
                  np.arange(4 * len(quads)).reshape(-1, 4), mats[mat])
    for name, (mat, parts) in furniture().items():
        verts, faces = [], []
        for corners, quads in parts:
            faces += [[len(verts) * 8 + i for i in q] for q in quads]
            verts.append(corners)
        _add_mesh(bpy, scene, name, np.concatenate(verts), np.array(faces), mats[mat])
    _add_mesh(bpy, scene, "Lamp", np.array(lamp_quad(), float), np.arange(4).reshape(1, 4), mats["Lamp"])

    common.add_sun(bpy, scene, 10.0, sun_direction(), (7.0, 2.5, 3.5))
    common.add_sky(bpy, scene, (0.4, 0.6, 1.0))
    common.add_camera(bpy, scene, *CAMERA, (640, 480))
    return scene


def _add_mesh(bpy, scene, name, verts, faces, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(np.asarray(verts, float).tolist(), [], np.asarray(faces).tolist())
    mesh.materials.append(mat)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj
