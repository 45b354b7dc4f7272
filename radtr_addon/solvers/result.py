"""What a solve returns: radiosity, convergence history, timings and the energy balance."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _zeros3():
    return np.zeros(3)


@dataclass
class SolveResult:
    """Radiosity ``B`` (n, 3) in W/m^2 and the power books of the solve, in W per channel.

    ``emitted = absorbed + escaped + blocked + unshot`` holds by construction for every
    solver (``unshot`` is the residual power still to be distributed); tests check the
    parts against independent estimates (an explicit window, Cycles).
    """

    B: np.ndarray
    irradiance: np.ndarray              # H (n, 3), W/m^2 arriving; B = E + rho H
    iterations: int
    converged: bool
    residual_history: list[float] = field(default_factory=list)  # residual / emitted power
    times: list[float] = field(default_factory=list)             # seconds at each history entry
    seconds: dict[str, float] = field(default_factory=dict)
    method: str = ""
    emitted: np.ndarray = field(default_factory=_zeros3)
    absorbed: np.ndarray = field(default_factory=_zeros3)
    escaped: np.ndarray = field(default_factory=_zeros3)
    blocked: np.ndarray = field(default_factory=_zeros3)
    unshot: np.ndarray = field(default_factory=_zeros3)
    ambient: np.ndarray = field(default_factory=_zeros3)   # shooting's ambient irradiance estimate, W/m^2

    @property
    def residual(self) -> float:
        return self.residual_history[-1] if self.residual_history else 1.0

    def balance_error(self) -> float:
        """|emitted - (absorbed + escaped + blocked + unshot)| / emitted, worst channel."""
        books = self.absorbed + self.escaped + self.blocked + self.unshot
        scale = np.where(self.emitted > 0, self.emitted, 1.0)
        return float(np.max(np.abs(self.emitted - books) / scale))

    def books(self, source: str = "") -> str:
        """The power emitted per channel, and where it went as shares of it (channels
        summed): a loss shows in ``escaped`` (light that left the scene, or that the
        hierarchical links lost). ``source``: what else the emitted power counts, said
        beside its channels (the Light objects' and the World's light, which joins the
        emission once reflected)."""
        total = float(self.emitted.sum())
        if total <= 0:
            return "no light emitted"
        parts = {"absorbed": self.absorbed, "escaped": self.escaped, "blocked": self.blocked, "unshot": self.unshot}
        shares = ", ".join(f"{name} {round(float(v.sum()) / total, 3) + 0.0:.1%}" for name, v in parts.items()
                           if name != "unshot" or v.sum() > 0)             # + 0.0: no "-0.0%"
        watts = ", ".join(f"{float(w):.4g}" for w in self.emitted)
        return f"emitted {watts} W (R, G, B{source}): {shares}"

    def display(self, rho: np.ndarray) -> np.ndarray:
        """B plus the ambient term rho x ambient (after Cohen et al. 1988), for showing partial solves."""
        return self.B + rho * self.ambient
