"""Priority queue of unshot power: the next shooter without scanning every patch.

A shot only ever raises the unshot power of the patches it reaches (reflectances and form
factors are non-negative) and sets the shooter's to zero. So a two-level tournament is
enough: the power per patch, and the maximum of each block of about sqrt(n) patches.
Raising values updates their blocks' maxima with one ``np.maximum.at``; popping scans the
block maxima and then one block, O(sqrt n) instead of O(n), and rescans only the
shooter's block.
"""
from __future__ import annotations

import numpy as np


class ShooterQueue:
    """Max-queue over ``values`` (n,) that only grow, except for the popped entry."""

    def __init__(self, values: np.ndarray):
        self.values = np.array(values, dtype=np.float64)
        n = len(self.values)
        self.block = max(int(np.sqrt(n)), 1)
        pad = -(-n // self.block) * self.block - n
        self._padded = np.concatenate([self.values, np.full(pad, -np.inf)])
        self.values = self._padded[:n]                     # a view: one array to keep current
        self.maxima = self._padded.reshape(-1, self.block).max(axis=1)

    def raise_to(self, ids: np.ndarray, values: np.ndarray):
        """Set ``values[ids]`` to new values, none of them lower than before."""
        self.values[ids] = values
        np.maximum.at(self.maxima, ids // self.block, values)

    def top(self) -> int:
        """Index of the largest value (the lowest index among ties)."""
        b = int(np.argmax(self.maxima))
        start = b * self.block
        return start + int(np.argmax(self._padded[start:start + self.block]))

    def pop(self) -> int:
        """Index of the largest value, which is set to zero."""
        i = self.top()
        self.values[i] = 0.0
        b = i // self.block
        self.maxima[b] = self._padded[b * self.block:(b + 1) * self.block].max()
        return i
