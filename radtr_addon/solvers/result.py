"""What a solve returns: radiosity, convergence history, timings and the energy balance."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class SolveResult:
    """Radiosity ``B`` (n, 3) in W/m^2 and the power books of the solve, in W per channel.

    ``emitted = absorbed + escaped + blocked + unshot`` holds by construction of the shooting
    updates; tests check it against independent estimates (an explicit window, Cycles).
    """

    B: np.ndarray
    irradiance: np.ndarray              # H (n, 3), W/m^2 arriving; B = E + rho H
    iterations: int
    converged: bool
    residual_history: list[float] = field(default_factory=list)  # unshot / emitted power
    seconds: dict[str, float] = field(default_factory=dict)
    emitted: np.ndarray = field(default_factory=lambda: np.zeros(3))
    absorbed: np.ndarray = field(default_factory=lambda: np.zeros(3))
    escaped: np.ndarray = field(default_factory=lambda: np.zeros(3))
    blocked: np.ndarray = field(default_factory=lambda: np.zeros(3))
    unshot: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def balance_error(self) -> float:
        """|emitted - (absorbed + escaped + blocked + unshot)| / emitted, worst channel."""
        books = self.absorbed + self.escaped + self.blocked + self.unshot
        scale = np.where(self.emitted > 0, self.emitted, 1.0)
        return float(np.max(np.abs(self.emitted - books) / scale))
