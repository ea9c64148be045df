"""The report of a design solve: cost, constraint violations, durations, IPOPT status."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any


@dataclass(frozen=True, kw_only=True)
class DesignReport:
    r"""What IPOPT reached on the program of a cycle.

    Attributes:
        status: IPOPT's return status (``Solve_Succeeded``, ``Infeasible_Problem_Detected``...).
        success: Whether IPOPT converged to its tolerance.
        iterations: IPOPT iterations.
        cost: Value of the (unscaled) weighted cost.
        cost_terms: Value of each cost term before weighting (effort [N² m² s], impulse
            [N² s²], time [s], force [N² s], smoothness [N² m²/s]).
        durations: Duration of each phase in [s].
        impulses: Impulse of each impact in [N s], in cycle order.
        max_violation: Largest violation of any constraint, in its own units.
        violations: Largest violation of each named constraint group.
        inf_pr: IPOPT's primal infeasibility at the last iterate.
        inf_du: IPOPT's dual infeasibility at the last iterate (of the scaled cost).
        stationarity: :math:`\|\nabla f + J_g^T \lambda\|_\infty` at the last iterate,
            computed from casadi's Jacobians and IPOPT's multipliers (scaled cost).
        complementarity: Largest :math:`|\lambda_i|` times the distance of constraint i to its
            nearer bound, inequalities only.
        multiplier_sign_error: Largest multiplier of the wrong sign for its active bound.
        cost_scale: The cost is divided by this for IPOPT (its value at the warm start).
        cpu_seconds: Where the solve's CPU time went, in [s]: ``solve`` (the whole of it),
            ``hessian`` (the Lagrangian's Hessian), ``jacobian`` (the constraints'
            Jacobian), ``functions`` (cost, constraints, cost gradient) and ``rest``
            (casadi building the derivative Functions, IPOPT's own linear algebra).
        hessian_calls: Evaluations of the Lagrangian's Hessian (one per iteration with the
            exact Hessian, none with ``limited-memory``).
    """

    status: str
    success: bool
    iterations: int
    cost: float
    cost_terms: dict[str, float] = field(default_factory=dict)
    durations: dict[str, float] = field(default_factory=dict)
    impulses: list[float] = field(default_factory=list)
    max_violation: float = math.nan
    violations: dict[str, float] = field(default_factory=dict)
    inf_pr: float = math.nan
    inf_du: float = math.nan
    stationarity: float = math.nan
    complementarity: float = math.nan
    multiplier_sign_error: float = math.nan
    cost_scale: float = 1.0
    cpu_seconds: dict[str, float] = field(default_factory=dict)
    hessian_calls: int = 0

    @property
    def period(self) -> float:
        """Period of the cycle in [s]."""
        return float(sum(self.durations.values()))

    def to_dict(self) -> dict[str, Any]:
        """The report as JSON-ready values."""
        table = asdict(self)
        table["period"] = self.period
        return table

    def save(self, path: str | Path) -> None:
        """Write the report as JSON."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=2, default=float) + "\n")

    def markdown(self) -> str:
        """The report as a Markdown page."""
        lines = [
            "# Designed cycle",
            "",
            f"- IPOPT status: `{self.status}` ({self.iterations} iterations)",
            f"- cost: {self.cost:.6g}",
            f"- period: {self.period:.6g} s",
            f"- max constraint violation: {self.max_violation:.3g}",
            f"- inf_pr: {self.inf_pr:.3g}, inf_du: {self.inf_du:.3g}, stationarity: "
            f"{self.stationarity:.3g}, complementarity: {self.complementarity:.3g}",
            *self._cpu_line(),
            "",
            "| phase | duration [s] |",
            "|---|---|",
            *(f"| {name} | {value:.6g} |" for name, value in self.durations.items()),
            "",
            "| cost term | value |",
            "|---|---|",
            *(f"| {name} | {value:.6g} |" for name, value in self.cost_terms.items()),
            "",
            "| impact | impulse [N s] |",
            "|---|---|",
            *(f"| {k + 1} | {value:.6g} |" for k, value in enumerate(self.impulses)),
            "",
            "| constraint | largest violation |",
            "|---|---|",
            *(f"| {name} | {value:.3g} |" for name, value in self.violations.items()),
            "",
        ]
        return "\n".join(lines)

    def _cpu_line(self) -> list[str]:
        """The solve's CPU split as one list item (none when it was not measured)."""
        seconds = self.cpu_seconds
        if not seconds:
            return []
        parts = ", ".join(
            f"{name} {seconds[name]:.3g} s" for name in ("hessian", "jacobian", "functions", "rest")
        )
        return [
            f"- CPU time of the solve: {seconds['solve']:.3g} s ({parts}; "
            f"{self.hessian_calls} Hessian evaluations)"
        ]
