"""Convergence measures: observed order, the book's step-to-step difference, and the comparison
of a printed book value with a computed one."""
from __future__ import annotations

import math
from dataclasses import dataclass


def observed_order(e1: float, e2: float, h1: float, h2: float) -> float | None:
    """p = log(e1/e2) / log(h1/h2), or None when an error is zero or not finite."""
    if not (e1 > 0 and e2 > 0 and math.isfinite(e1) and math.isfinite(e2)) or h1 == h2:
        return None
    return math.log(e1 / e2) / math.log(h1 / h2)


def delta_percent(x_h1: float, x_h2: float) -> float:
    """The book's step-to-step difference, section 4.1.3: Delta = (x(h1)/x(h2) - 1) * 100."""
    return (x_h1 / x_h2 - 1.0) * 100.0


@dataclass(frozen=True)
class BookValue:
    """A number as printed in the book: its value and how many decimals it was printed with."""

    text: str

    @property
    def value(self) -> float:
        return float(self.text.replace(",", ".").replace("−", "-"))

    @property
    def decimals(self) -> int:
        t = self.text.replace(",", ".")
        return len(t.split(".")[1]) if "." in t else 0

    def compare(self, computed: float) -> str:
        """'agrees' (within half a unit of the last printed digit), 'agrees (truncated)' (within
        one unit, the book having cut the digits instead of rounding) or 'FLAG'."""
        unit = 10.0 ** (-self.decimals)
        d = abs(computed - self.value)
        if d <= 0.5 * unit * (1 + 1e-9) + 1e-15:
            return "agrees"
        if d < unit and abs(self.value) < abs(computed) and self.value * computed >= 0:
            return "agrees (truncated)"
        return "FLAG"
