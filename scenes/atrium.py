"""A Sponza-class atrium, built procedurally: a courtyard open to the sky, ringed by two
storeys of arcades.

Metres, z up, the court centred on the origin. The arcade centre lines run round a rectangle
of 27 x 15 m (9 x 5 bays of 3 m); galleries 3.7 m deep behind the arcades (outer walls at
x = +-17.5, y = +-11.5). Objects (materials: ``Stone`` 0.6 0.55 0.48, ``Plaster`` 0.7 0.66
0.58, ``Paving`` 0.45 0.42 0.38, ``Red_Cloth`` 0.5 0.05 0.04, ``Lamp``; Principled BSDF,
roughness 1, specular 0):

- ``Floor``: one quad over the whole footprint, z = 0.
- ``Walls``: the outer walls of both storeys (z 0..6.2 and 6.5..11.6), normals in.
- ``Slabs``: the gallery floor slab (z 6.2..6.5) and the gallery roof (z 11.6..11.9), each a
  ring of quads around the court with its court-facing edge flush with the arcade fronts.
- ``Columns``: 28 per storey at the bay corners, each a 0.6 x 0.6 m plinth, a 20-sided
  turned column (moulded base, tapering shaft, flared capital) and a 0.6 x 0.6 x 0.15 m
  abacus; the arches spring from the abacus tops at z 4.5 (ground storey) and 10.0 (upper).
- ``Arches``: 28 bays per storey, each a 0.6 m thick wall up to the slab above, pierced by a
  half-round arch of radius 1.2 m in 24 segments (front, back and soffit); where two sides
  meet, their walls close the corner pier.
- ``Balustrades``: in each upper bay, a plinth beam, six 8-sided turned balusters and a rail
  (z 6.5..7.55).
- ``Drapes``: four red cloths hanging in the ground-floor galleries of the north and south
  sides (bays 2 and 8 of 9), 0.5 m behind the arcades' back faces, from the slab (z 6.2)
  down to z 1.2, folded in depth (two sheets 1 cm apart, closed at the sides and bottom).
- ``Lamps``: eight 0.5 x 0.5 m emitting quads facing down, one in the middle bay of each
  gallery, 0.5 m below its ceiling, emission strength 30 (two-sided), so the scene also
  solves with the sun hidden.
- ``Sun`` (strength 5 W/m^2, elevation 50 degrees), World ``Sky`` (Background 0.45 0.6 0.9,
  strength 1) seen through the open court, and ``Camera`` in the court looking along it at
  the arcades (18 mm lens, 960 x 540).

Contacts: plinths and the walls stand on the floor or slab (gap 0); balusters stand on
their beam; the drapes touch the ceiling; the arcade walls meet the slabs. Faces that lie
on another surface are left out. Every face's normal faces free space.
65,474 input triangles (32,745 faces); it builds in well under a second with numpy and
``foreach_set``.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

_spec = importlib.util.spec_from_file_location("radtr_scene_common", Path(__file__).with_name("_common.py"))
common = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(common)

NX, NY = 9, 5                    # bays along x and y
SPAN = 3.0                       # bay width (column centre to column centre)
A = 0.3                          # half width of plinths and abaci, half thickness of the arcade walls
DEPTH = 4.0                      # arcade centre line to outer wall
CX, CY = NX * SPAN / 2, NY * SPAN / 2
OUTER = (CX + DEPTH, CY + DEPTH)
SIDES = 20                       # column sides
SEGMENTS = 24                    # arch segments (a multiple of 4)
SLAB = 0.3

#: Storeys: floor z, plinth and base heights, shaft, capital, abacus, top (slab underside).
STOREYS = (
    dict(floor=0.0, plinth=0.3, base=0.3, shaft=3.3, capital=0.45, abacus=0.15, top=6.2),
    dict(floor=6.5, plinth=0.25, base=0.25, shaft=2.75, capital=0.35, abacus=0.15, top=11.6),
)
#: Column profile (radius at each fraction of the base, shaft and capital heights).
BASE_PROFILE = ((0.28, 0.0), (0.29, 0.25), (0.285, 0.5), (0.26, 0.7), (0.25, 0.85), (0.24, 1.0))
SHAFT_PROFILE = ((0.235, 0.3), (0.228, 0.6), (0.22, 0.85), (0.215, 1.0))
CAPITAL_PROFILE = ((0.225, 0.15), (0.24, 0.35), (0.26, 0.6), (0.28, 0.85), (0.29, 1.0))

BALUSTERS = 6                    # per bay
BALUSTER_SIDES = 8
BALUSTER_PROFILE = ((0.05, 0.0), (0.07, 0.12), (0.045, 0.3), (0.08, 0.55), (0.06, 0.75),
                    (0.04, 0.9), (0.05, 1.0))
BEAM_TOP, RAIL = 0.15, (0.9, 0.15)       # beam height; rail bottom above the floor, height

DRAPES = (("S", 1), ("S", 7), ("N", 1), ("N", 7))   # side and bay
DRAPE_GRID = (40, 12)            # quads across, down
LAMP_SIZE, LAMP_DROP = 0.5, 0.5

MATERIALS = {  # name: (RGB reflectance, emission strength, emission colour)
    "Stone": ((0.6, 0.55, 0.48), 0.0, None),
    "Plaster": ((0.7, 0.66, 0.58), 0.0, None),
    "Paving": ((0.45, 0.42, 0.38), 0.0, None),
    "Red_Cloth": ((0.5, 0.05, 0.04), 0.0, None),
    "Lamp": ((0.8, 0.8, 0.8), 30.0, (1.0, 0.85, 0.6)),
}

#: The four sides: origin (a court corner), direction along the side, inward normal.
SIDE_FRAMES = {
    "S": ((-CX, -CY), (1.0, 0.0), (0.0, 1.0), NX),
    "E": ((CX, -CY), (0.0, 1.0), (-1.0, 0.0), NY),
    "N": ((CX, CY), (-1.0, 0.0), (0.0, -1.0), NX),
    "W": ((-CX, CY), (0.0, -1.0), (1.0, 0.0), NY),
}
CAMERA = ((-12.0, -4.0, 1.7), (4.0, 2.0, 4.5))   # location, target
SUN_ELEVATION, SUN_AZIMUTH = 50.0, 30.0
#: Points in the open: the camera, the court, both storeys of galleries (for checks).
FREE_POINTS = (CAMERA[0], (0.0, 0.0, 3.0), (0.0, -9.5, 3.0), (-15.5, 0.0, 2.0), (0.0, 9.5, 8.5), (15.5, 0.0, 9.0))

_BOX_FACES = {
    "-z": (0, 2, 3, 1), "+z": (4, 5, 7, 6), "-y": (0, 1, 5, 4),
    "+y": (2, 6, 7, 3), "-x": (0, 4, 6, 2), "+x": (1, 3, 7, 5),
}


class Parts:
    """Vertices and faces (quads, triangles) gathered for one object."""

    def __init__(self):
        self.verts, self.quads, self.tris, self.n = [], [], [], 0

    def add(self, verts, quads=None, tris=None):
        verts = np.asarray(verts, float).reshape(-1, 3)
        if quads is not None and len(quads):
            self.quads.append(np.asarray(quads).reshape(-1, 4) + self.n)
        if tris is not None and len(tris):
            self.tris.append(np.asarray(tris).reshape(-1, 3) + self.n)
        self.verts.append(verts)
        self.n += len(verts)

    def box(self, lo, hi, skip=(), frame=None):
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        corners = np.array([[(hi if i & 1 else lo)[0], (hi if i & 2 else lo)[1], (hi if i & 4 else lo)[2]]
                            for i in range(8)])
        if frame is not None:
            corners = frame(corners)
        self.add(corners, [f for k, f in _BOX_FACES.items() if k not in skip])

    def arrays(self):
        """(verts, quads, tris) with degenerate quads turned into triangles and unused vertices dropped."""
        verts = np.concatenate(self.verts)
        quads = np.concatenate(self.quads) if self.quads else np.zeros((0, 4), int)
        tris = np.concatenate(self.tris) if self.tris else np.zeros((0, 3), int)
        p = verts[quads]
        same = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2) < 1e-12      # edge k -> k+1 has length 0
        bad = same.any(axis=1)
        extra = [np.delete(q, int(np.argmax(s)))[None] for q, s in zip(quads[bad], same[bad]) if s.sum() == 1]
        quads = quads[~bad]
        tris = np.concatenate([tris, *extra]) if extra else tris
        used = np.zeros(len(verts), bool)
        used[quads.ravel()] = used[tris.ravel()] = True
        remap = np.cumsum(used) - 1
        return verts[used], remap[quads], remap[tris]


def lathe(profile, sides):
    """Surface of revolution about z of ``profile`` ((r, z) rows, z rising): (verts, quads), normals out."""
    profile = np.asarray(profile, float)
    angle = 2 * np.pi * np.arange(sides) / sides
    verts = np.stack([np.outer(profile[:, 0], np.cos(angle)), np.outer(profile[:, 0], np.sin(angle)),
                      np.repeat(profile[:, 1:2], sides, axis=1)], axis=-1).reshape(-1, 3)
    ring, j = np.meshgrid(np.arange(len(profile) - 1), np.arange(sides), indexing="ij")
    j1 = (j + 1) % sides
    quads = np.stack([ring * sides + j, ring * sides + j1, (ring + 1) * sides + j1, (ring + 1) * sides + j],
                     axis=-1).reshape(-1, 4)
    return verts, quads


def tile(verts, quads, offsets):
    """Copies of (verts, quads) moved by each of ``offsets`` (k, 3)."""
    offsets = np.asarray(offsets, float)
    v = (verts[None] + offsets[:, None]).reshape(-1, 3)
    q = (quads[None] + len(verts) * np.arange(len(offsets))[:, None, None]).reshape(-1, 4)
    return v, q


def side_frame(side):
    """Local (u along the side, w towards the court, z) to world, for one side of the court."""
    (ox, oy), t, n, _ = SIDE_FRAMES[side]
    m = np.array([[t[0], n[0], 0.0], [t[1], n[1], 0.0], [0.0, 0.0, 1.0]])
    o = np.array([ox, oy, 0.0])
    return lambda p: np.asarray(p, float) @ m.T + o


def column_positions():
    xs = -CX + SPAN * np.arange(NX + 1)
    ys = -CY + SPAN * np.arange(1, NY)
    pts = [(x, y) for x in xs for y in (-CY, CY)] + [(x, y) for y in ys for x in (-CX, CX)]
    return np.array(pts)


def springing(st):
    return st["floor"] + st["plinth"] + st["base"] + st["shaft"] + st["capital"] + st["abacus"]


def columns(parts: Parts):
    xy = column_positions()
    for st in STOREYS:
        z0 = st["floor"] + st["plinth"]
        profile = ([(r, z0 + f * st["base"]) for r, f in BASE_PROFILE]
                   + [(r, z0 + st["base"] + f * st["shaft"]) for r, f in SHAFT_PROFILE]
                   + [(r, z0 + st["base"] + st["shaft"] + f * st["capital"]) for r, f in CAPITAL_PROFILE])
        v, q = lathe(profile, SIDES)
        offsets = np.column_stack([xy, np.zeros(len(xy))])
        parts.add(*tile(v, q, offsets))
        hs = springing(st)
        for x, y in xy:
            parts.box((x - A, y - A, st["floor"]), (x + A, y + A, z0), skip=("-z",))
            parts.box((x - A, y - A, hs - st["abacus"]), (x + A, y + A, hs), skip=("+z",))


def arch_bay(parts: Parts, frame, u0, hs, top, first, last):
    """One bay's wall above the springing (z ``hs``) up to ``top``, with its half-round arch.

    Local frame: u along the side, w towards the court (front at w = +A, back at w = -A).
    At a corner (``first``/``last``) the front stops at the other side's front plane and the
    back runs on to the other side's back plane, so the two walls close the corner pier.
    """
    m = SEGMENTS
    u1, uc, radius, height = u0 + SPAN, u0 + SPAN / 2, SPAN / 2 - A, top - hs
    theta = np.pi * (1 - np.arange(m + 1) / m)
    arc = np.column_stack([uc + radius * np.cos(theta), hs + radius * np.sin(theta)])

    def outline(left, right):
        k = np.arange(m + 1)
        q = np.empty((m + 1, 2))
        a, b = k <= m // 4, k >= 3 * m // 4
        q[a] = np.column_stack([np.full(a.sum(), left), hs + height * k[a] / (m // 4)])
        mid = ~a & ~b
        q[mid] = np.column_stack([left + (right - left) * (k[mid] - m // 4) / (m // 2), np.full(mid.sum(), top)])
        q[b] = np.column_stack([np.full(b.sum(), right), hs + height * (m - k[b]) / (m // 4)])
        return q

    def lift(uv, w):
        return frame(np.column_stack([uv[:, 0], np.full(len(uv), w), uv[:, 1]]))

    k = np.arange(m)
    for w, left, right, front in ((A, u0 + A if first else u0, u1 - A if last else u1, True),
                                  (-A, u0 - A if first else u0, u1 + A if last else u1, False)):
        verts = np.concatenate([lift(arc, w), lift(outline(left, right), w)])
        p, q = k, k + m + 1
        quads = np.column_stack([p, q, q + 1, p + 1] if front else [p, p + 1, q + 1, q])
        parts.add(verts, quads)
    verts = np.concatenate([lift(arc, A), lift(arc, -A)])
    parts.add(verts, np.column_stack([k, k + 1, k + m + 2, k + m + 1]))


def arches(parts: Parts):
    for st in STOREYS:
        hs = springing(st)
        for side, (_, _, _, bays) in SIDE_FRAMES.items():
            frame = side_frame(side)
            for b in range(bays):
                arch_bay(parts, frame, b * SPAN, hs, st["top"], b == 0, b == bays - 1)


def balustrades(parts: Parts):
    st = STOREYS[1]
    z = st["floor"]
    v, q = lathe([(r, z + BEAM_TOP + f * (RAIL[0] - BEAM_TOP)) for r, f in BALUSTER_PROFILE],
                 BALUSTER_SIDES)
    clear = SPAN - 2 * A
    for side, (_, _, _, bays) in SIDE_FRAMES.items():
        frame = side_frame(side)
        for b in range(bays):
            u0 = b * SPAN + A
            parts.box((u0, -0.15, z), (u0 + clear, 0.15, z + BEAM_TOP), skip=("-z", "-x", "+x"), frame=frame)
            parts.box((u0, -0.18, z + RAIL[0]), (u0 + clear, 0.18, z + RAIL[0] + RAIL[1]), frame=frame)
            us = u0 + clear * (np.arange(BALUSTERS) + 0.5) / BALUSTERS
            parts.add(*tile(v, q, frame(np.column_stack([us, np.zeros(BALUSTERS), np.zeros(BALUSTERS)]))))


def ring(parts: Parts, z, inner, up):
    """The rectangle OUTER minus ``inner`` (half sizes) at height z, as 8 quads facing up or down."""
    xs = (-OUTER[0], -inner[0], inner[0], OUTER[0])
    ys = (-OUTER[1], -inner[1], inner[1], OUTER[1])
    for i in range(3):
        for j in range(3):
            if (i, j) == (1, 1):
                continue
            quad = [(xs[i], ys[j], z), (xs[i + 1], ys[j], z), (xs[i + 1], ys[j + 1], z), (xs[i], ys[j + 1], z)]
            parts.add(quad if up else quad[::-1], [[0, 1, 2, 3]])


def rect_band(parts: Parts, half, z0, z1, inward):
    """Four vertical quads round the rectangle of half sizes ``half`` from z0 to z1, facing in or out."""
    hx, hy = half
    corners = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
    for (xa, ya), (xb, yb) in zip(corners, corners[1:] + corners[:1]):
        quad = [(xa, ya, z0), (xb, yb, z0), (xb, yb, z1), (xa, ya, z1)]   # counter-clockwise: faces out
        parts.add(quad[::-1] if inward else quad, [[0, 1, 2, 3]])


def slabs(parts: Parts):
    front, back = (CX - A, CY - A), (CX + A, CY + A)
    for st in STOREYS:
        top = st["top"]
        ring(parts, top, back, up=False)
        ring(parts, top + SLAB, front, up=True)
        rect_band(parts, front, top, top + SLAB, inward=True)
    rect_band(parts, OUTER, STOREYS[1]["top"], STOREYS[1]["top"] + SLAB, inward=False)


def walls(parts: Parts):
    for st in STOREYS:
        rect_band(parts, OUTER, st["floor"], st["top"], inward=True)


def drapes(parts: Parts):
    nu, nv = DRAPE_GRID
    top, bottom, inset, behind, fold, thick = STOREYS[0]["top"], 1.2, 0.25, 0.5, 0.07, 0.01
    for side, bay in DRAPES:
        frame = side_frame(side)
        u = bay * SPAN + inset + (SPAN - 2 * inset) * np.arange(nu + 1) / nu
        z = top - (top - bottom) * np.arange(nv + 1) / nv
        uu, zz = np.meshgrid(u, z, indexing="ij")
        depth = fold * np.sin(2 * np.pi * (uu - u[0]) / 0.42) * (0.4 + 0.6 * (top - zz) / (top - bottom))
        w = -A - behind + depth
        g = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
        a, b, c, d = g[:-1, :-1], g[1:, :-1], g[1:, 1:], g[:-1, 1:]
        cells = np.stack([a, b, c, d], axis=-1).reshape(-1, 4)       # u right, z down: faces +w
        n = g.size
        front = frame(np.column_stack([uu.ravel(), (w + thick / 2).ravel(), zz.ravel()]))
        back = frame(np.column_stack([uu.ravel(), (w - thick / 2).ravel(), zz.ravel()]))
        verts = np.concatenate([front, back])
        quads = [cells, cells[:, ::-1] + n]
        bot = g[:, -1]
        quads.append(np.column_stack([bot[:-1], bot[1:], bot[1:] + n, bot[:-1] + n]))   # bottom edge, down
        for col, sign in ((g[0], 1), (g[-1], -1)):                                          # sides
            e = np.column_stack([col[:-1], col[1:], col[1:] + n, col[:-1] + n])
            quads.append(e if sign > 0 else e[:, ::-1])
        parts.add(verts, np.concatenate(quads))


def lamps(parts: Parts):
    h = LAMP_SIZE / 2
    for st in STOREYS:
        z = st["top"] - LAMP_DROP
        for side, (_, _, _, bays) in SIDE_FRAMES.items():
            frame = side_frame(side)
            uc, wc = bays * SPAN / 2, -(A + DEPTH) / 2
            quad = [(uc - h, wc - h, z), (uc - h, wc + h, z), (uc + h, wc + h, z), (uc + h, wc - h, z)]
            parts.add(frame(quad), [[0, 1, 2, 3]])


def floor(parts: Parts):
    ox, oy = OUTER
    parts.add([(-ox, -oy, 0.0), (ox, -oy, 0.0), (ox, oy, 0.0), (-ox, oy, 0.0)], [[0, 1, 2, 3]])


OBJECTS = {  # name: (material, builder)
    "Floor": ("Paving", floor),
    "Walls": ("Plaster", walls),
    "Slabs": ("Plaster", slabs),
    "Columns": ("Stone", columns),
    "Arches": ("Stone", arches),
    "Balustrades": ("Stone", balustrades),
    "Drapes": ("Red_Cloth", drapes),
    "Lamps": ("Lamp", lamps),
}


def geometry():
    """name: (material, verts, quads, tris) of every mesh object."""
    out = {}
    for name, (mat, builder) in OBJECTS.items():
        parts = Parts()
        builder(parts)
        out[name] = (mat, *parts.arrays())
    return out


def sun_direction() -> np.ndarray:
    el, az = math.radians(SUN_ELEVATION), math.radians(SUN_AZIMUTH)
    return np.array([-math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])


def build(bpy):
    """Add the atrium (objects, materials, sun, sky, camera) to the current scene; return it."""
    scene = bpy.context.scene
    mats = {name: common.material(bpy, name, *spec) for name, spec in MATERIALS.items()}
    for name, (mat, verts, quads, tris) in geometry().items():
        obj = bpy.data.objects.new(name, _mesh(bpy, name, verts, quads, tris))
        obj.data.materials.append(mats[mat])
        scene.collection.objects.link(obj)

    common.add_sun(bpy, scene, 5.0, sun_direction(), (0.0, 0.0, 20.0))
    common.add_sky(bpy, scene, (0.45, 0.6, 0.9))
    common.add_camera(bpy, scene, *CAMERA, (960, 540), clip_end=200.0)
    return scene


def _mesh(bpy, name, verts, quads, tris):
    """A mesh from numpy arrays in one go (``foreach_set``)."""
    mesh = bpy.data.meshes.new(name)
    loops = np.concatenate([quads.ravel(), tris.ravel()]).astype(np.int32)
    starts = np.concatenate([4 * np.arange(len(quads)), 4 * len(quads) + 3 * np.arange(len(tris))])
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.astype(np.float32).ravel())
    mesh.loops.add(len(loops))
    mesh.loops.foreach_set("vertex_index", loops)
    mesh.polygons.add(len(starts))
    mesh.polygons.foreach_set("loop_start", starts.astype(np.int32))
    mesh.update(calc_edges=True)
    return mesh
