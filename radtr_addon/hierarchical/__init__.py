"""Hierarchical radiosity (Hanrahan, Salzman and Aupperle 1991) with clustering (Smits, Arvo
and Greenberg 1994): each pair of surfaces exchanges light at the coarsest levels of the
node trees whose transfer is within the Quality bound epsilon, refined (lazily, no fixed
patch size) where light changes: near contacts, shadow boundaries, bright near fields.

``nodes``: cluster tree over the input triangles and element quadtrees below them;
``links``: transfer, error estimate and refinement of links; ``contacts``: where another
surface is close in front of part of a surface (gaps, resting objects); ``solve``: refine-solve rounds,
push-pull gathering, the adaptive leaves and crack-free vertex colours.
"""
from .solve import HierarchicalRadiosity, HierarchicalResult, HierarchicalSettings

__all__ = ["HierarchicalRadiosity", "HierarchicalResult", "HierarchicalSettings"]
