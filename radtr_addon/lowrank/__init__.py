"""Low-rank radiosity: precompute once from the patch hierarchy, relight every frame.

Derivation. Every solver solves B = E + R K B with K_ij = F_ji A_j / A_i (``solvers.base``).
Take the k nodes g of one hierarchy level as clusters and approximate the light patch i
gathers from a leaf j of cluster g by what it gathers from the cluster's representative
(centre) leaf rep(g), scaled by area:

    K_ij ~ K_i,rep(g) A_j / A_rep(g) = U_ig V_jg,   U_ig = A_rep F_rep->i / A_i,  V_jg = A_j / A_rep(g).

So K ~ U V^T with U (n x k) dense, from one form-factor render at each representative
(k renders, not n), and V (n x k) sparse, one entry per leaf (all 1 for equal-area
midpoint splits). Woodbury's identity then solves the approximated system exactly:

    B = (I - R U V^T)^-1 E = E + R U (I_k - V^T R U)^-1 V^T E = E - Y (V^T E),
    Y = -R U (I_k - V^T R U)^-1    (per channel, R = diag(rho_c)).

What is approximated is the variation of F_j->i over the cluster: small when i is far from
g, worst when i is near or inside g. With k = n (the leaf level) V = I and U = K, and the
solve is exact. Per frame we keep U once (not three Y's) and an LU of the k x k matrix per
channel: w = V^T E, z_c = M_c^-1 w_c, and all three channels in one n x k by k x 3 product,
B = E + rho * (U Z).

Several levels combined (``build_cut``): the clusters can be any cut through the hierarchy,
nodes of different levels covering every leaf once; V_jg = A_j / A_rep(g) is then not 1 for
all leaves. ``refined_cut`` starts from one level and splits the nodes that carry the most
light until the cut has the clusters asked for.
"""
from .factor import LowRank, build, build_cut, level_bytes, refined_cut

__all__ = ["LowRank", "build", "build_cut", "level_bytes", "refined_cut"]
