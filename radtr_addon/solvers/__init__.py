"""Radiosity solvers over form-factor rows; each returns a ``SolveResult``."""
from .result import SolveResult
from .shooting import ShootingSolver, shoot

__all__ = ["SolveResult", "ShootingSolver", "shoot"]
