"""Small test scenes with known form factors."""
import numpy as np

from radtr_addon.hierarchy import subdivide
from radtr_addon.scene import PatchScene

PARALLEL_UNIT_SQUARES = 0.199825      # distance 1, directly opposed
PERPENDICULAR_UNIT_SQUARES = 0.200044  # sharing an edge


def squares(top_z=1.0, perpendicular=False):
    """Unit square facing +z at z=0 and a second one facing it (or standing on its edge x=0)."""
    if perpendicular:
        v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [0, 1, 1]]
        t = [[0, 1, 2], [0, 2, 3], [0, 3, 5], [0, 5, 4]]
    else:
        v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, top_z], [1, 0, top_z], [1, 1, top_z], [0, 1, top_z]]
        t = [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]]
    return PatchScene(np.array(v, float), t, 0.5, 0.0, [0, 0, 1, 1], 0)


def cube(emission=1.0):
    """The closed unit cube, 12 triangles facing inwards."""
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    t = [[a, b, c] for a, b, c, d in quads] + [[a, c, d] for a, b, c, d in quads]
    return PatchScene(v, t, 0.5, emission, 0, 0)


def area_mean_ff(scene, make_method, max_area):
    """F from the first square (source ids 0, 1) to the second, area-averaged over its patches."""
    h = subdivide(scene, max_area, 1)
    leaves = h.leaves
    src = np.flatnonzero(h.source < 2)
    rows = make_method(leaves).rows(src)
    to_other = [r.values[h.source[r.indices] >= 2].sum() for r in rows]
    return np.dot(leaves.areas[src], to_other) / leaves.areas[src].sum()
