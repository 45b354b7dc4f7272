"""Form factors: F[i, j] = fraction of the energy leaving patch i that arrives at patch j.

A method returns sparse rows (``Row``): the patches hit, their form factors, and the
fractions that escape the scene (``escaped``) or hit the back side of a patch (``blocked``),
so that ``values.sum() + escaped + blocked`` is 1 up to the method's discretisation error.
"""
from .methods import METHODS, FormFactors, FormFactorSettings
from .rows import Row, RowCache

__all__ = ["METHODS", "FormFactorSettings", "FormFactors", "Row", "RowCache"]
