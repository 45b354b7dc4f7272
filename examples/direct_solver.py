"""An example of your own solver in RadTR's loop (``--solver user --user-solver
examples/direct_solver.py:solve``, or the Solver "User" in the N-panel), and of a per-frame
flashlight solve (back-end "user", ``examples/direct_solver.py:frame``).

It receives the sparse form factors F (row i: what patch i sees), the emission E and
reflectance rho (n x 3) and the patch areas, and returns the radiosity B (n x 3). This one
solves RadTR's system B = E + R K B, K = diag(1/A) F^T diag(A), with scipy's sparse LU.
"""
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def solve(F, E, rho, areas, **_):
    K = sp.diags(1.0 / areas) @ F.T @ sp.diags(areas)
    identity = sp.identity(len(areas), format="csc")
    return np.stack([spla.spsolve((identity - sp.diags(rho[:, c]) @ K).tocsc(), E[:, c]) for c in range(3)], axis=1)


def frame(E, U, V, rho, **_):
    """The flashlight's per-frame solve (back-end "user"): Woodbury on the low-rank factors,
    B = E + R U (I - V^T R U)^-1 V^T E, per channel."""
    k = U.shape[1]
    B = np.empty_like(E)
    for c in range(E.shape[1]):
        RU = rho[:, c, None] * U
        M = np.eye(k) - V.T @ RU
        B[:, c] = E[:, c] + RU @ np.linalg.solve(M, V.T @ E[:, c])
    return B
