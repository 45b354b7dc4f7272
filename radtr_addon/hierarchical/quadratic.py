"""Quadratic (P2) irradiance over an element: six nodal values, corners then edge midpoints.

A link does not hand its receiver one number but the gathered form factor at six points,
so how the light varies over a large receiver (a wall lit from near one end) survives the
push to its children: each child's nodal values are the parent's quadratic evaluated at the
child's nodes (``PUSH``). A hierarchy that mixes coarse and fine links then still sums, at
every point, the form factors of a partition of the scene (1 in a closed one), where a
constant per link would leave each leaf the mean of a coarser receiver.

Nodes sit ``INSET`` of the way towards the centroid (an edge on a contact line is a singular
line of F). A link's quadratic is fitted (``fitted``) to F at the nodes, at ``CHECK`` (the
centroid and the three points halfway from it to the corners, where a peak between the
nodes shows) and at a degree-6 rule's points, with the rule's mean; its worst miss at them
is its error.
Barycentric order: corners a, b, c, then midpoints of bc, ca, ab.
"""
from __future__ import annotations

import numpy as np

INSET = 0.05
_REF = np.vstack([np.eye(3), [[0, .5, .5], [.5, 0, .5], [.5, .5, 0]]])
CHECK = np.vstack([[[1 / 3] * 3], (np.eye(3) + 1 / 3) / 2])
#: Barycentric points where a link's form factor is evaluated: the six nodes, then ``CHECK``.
POINTS = np.vstack([(1 - INSET) * _REF + INSET / 3, CHECK])

#: Dunavant's 12-point rule, exact for polynomials of degree 6 on a triangle: barycentric points
#: and weights (summing to 1) of a link's mean form factor over its receiver
#: (``links.Evaluator._elements``), where the quadratic cannot follow a steep rise of F.
_A6, _B6, _C6, _D6, _E6, _F6, _G6 = (0.501426509658179, 0.249286745170910, 0.873821971016996, 0.063089014491502,
                                     0.053145049844817, 0.310352451033784, 0.636502499121399)
RULE_POINTS = np.array([(_A6, _B6, _B6), (_B6, _A6, _B6), (_B6, _B6, _A6), (_C6, _D6, _D6), (_D6, _C6, _D6),
                        (_D6, _D6, _C6), (_E6, _F6, _G6), (_E6, _G6, _F6), (_F6, _E6, _G6), (_F6, _G6, _E6),
                        (_G6, _E6, _F6), (_G6, _F6, _E6)])
RULE_WEIGHTS = np.array([0.116786275726379] * 3 + [0.050844906370207] * 3 + [0.082851075618374] * 6)


def basis(bary: np.ndarray) -> np.ndarray:
    """P2 basis values (m, 6) at barycentric points (m, 3) of the inset triangle."""
    ref = (np.asarray(bary, float) - INSET / 3) / (1 - INSET)
    l1, l2, l3 = ref.T
    return np.stack([l1 * (2 * l1 - 1), l2 * (2 * l2 - 1), l3 * (2 * l3 - 1), 4 * l2 * l3, 4 * l3 * l1, 4 * l1 * l2], 1)


#: Values (4, 6) at the check points from the six nodal values.
AT_CHECK = basis(CHECK)
#: Mean over the whole triangle (exact for a quadratic: its mean at the three edge midpoints).
MEAN = basis(_REF[3:]).mean(axis=0)
#: Values at the triangle's corners (3, 6).
AT_CORNERS = basis(np.eye(3))

# children of ``nodes.Nodes.split``, as corners in the parent's barycentric coordinates
_A, _B, _C = np.eye(3)
_AB, _BC, _CA = (_A + _B) / 2, (_B + _C) / 2, (_C + _A) / 2
_CHILDREN = [(_AB, _BC, _CA), (_A, _AB, _CA), (_AB, _B, _BC), (_CA, _BC, _C)]
#: (4, 6, 6): a child's nodal values from its parent's, per child slot.
PUSH = np.stack([basis(POINTS[:6] @ np.array(corners)) for corners in _CHILDREN])

#: Values (22, 6) at ``POINTS`` then ``RULE_POINTS`` from the six nodal values.
AT_FIT = basis(np.vstack([POINTS, RULE_POINTS]))


def _mean_fit() -> tuple[np.ndarray, np.ndarray]:
    """(6, P) least-squares fit of nodal values to values at ``POINTS`` and ``RULE_POINTS``, and
    (6,) the correction that sets the fit's mean to a given one (Lagrange: c + g (mu - MEAN.c) /
    (MEAN.g), g = (Phi^T Phi)^-1 MEAN)."""
    inv = np.linalg.inv(AT_FIT.T @ AT_FIT)
    g = inv @ MEAN
    return inv @ AT_FIT.T, g / (MEAN @ g)


FIT, FIT_MEAN = _mean_fit()


def fitted(values: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """Nodal values (L, 6) of the quadratic nearest (least squares) to ``values`` (L, P) at
    ``POINTS`` then ``RULE_POINTS``, with its mean over the triangle ``mean`` (L,); nodes
    below 0 are set to 0 and the rest scaled to that mean (the fit dips below 0 where F
    falls to 0 at a horizon, and a lone link would push negative light to the leaves there)."""
    c = values @ FIT.T
    c += (mean - c @ MEAN)[:, None] * FIT_MEAN
    c = np.maximum(c, 0.0)
    m = c @ MEAN
    return c * np.where(m > 0, mean / np.where(m > 0, m, 1.0), 1.0)[:, None]
