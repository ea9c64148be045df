r"""Reused, warm-started proxsuite dense QPs: the one place ucontrol imports proxsuite.

The contact problems of a time-stepping run have the same shape step after step and change
little between steps, so one ``proxsuite.proxqp.dense.QP`` object is kept per shape, updated in
place and started from its previous solution. Both the frictionless LCP
(:mod:`ucontrol.solvers.proxsuite_lcp`) and the Tresca problems of the Coulomb fixed point
(:mod:`ucontrol.solvers.proxsuite_coulomb`) are solved through :class:`WarmStartedQP`:

.. math:: \min_x \tfrac12 x^T H x + g^T x \quad \text{s.t.} \quad l \le C x \le u,
          \quad l_\text{box} \le x \le u_\text{box}.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import proxsuite
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.exceptions import InvalidParameterError

_WARM_START = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
_GIVEN_START = proxsuite.proxqp.InitialGuess.WARM_START

#: Stands for an infinite bound in proxsuite's constraints.
INFINITY = 1e20
#: proxsuite's status of a solved QP.
QP_SOLVED = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED

Vector = NDArray[np.float64]


class WarmStartedQP:
    """Dense proxsuite QPs, one object per (variables, inequalities, box) shape.

    Args:
        eps_abs: Absolute tolerance of proxsuite, in the units of the constraints.
        max_iter: Iteration cap of proxsuite.
        bounds_change: The bounds change between solves (the Tresca QPs of a fixed point):
            each solve then starts from the previous primal solution only, its multipliers
            from 0. Warm-started with the previous multipliers, proxsuite's primal and dual
            residuals accept the previous solution after zero iterations although its
            multipliers sit on constraints that are no longer active; given them with the
            inactive ones zeroed, it was measured to stall for thousands of iterations.
        fixed_constraints: Every solve of a shape has the constraints (``C``, ``l``, ``u``,
            box) of its first solve: only ``H`` and ``g`` are handed to proxsuite again (the
            frictionless LCP, whose only constraints are ``P >= 0``). The results are those
            of a QP updated with every array, for two arrays handed over instead of five (to
            round-off: proxsuite's dense results depend on the memory alignment of its buffers,
            measured to change the last bits of x when only the alignment of ``H`` changes).

    Raises:
        InvalidParameterError: Both ``bounds_change`` and ``fixed_constraints``.
    """

    def __init__(
        self,
        *,
        eps_abs: float = 1e-10,
        max_iter: int = 5000,
        bounds_change: bool = False,
        fixed_constraints: bool = False,
    ) -> None:
        self.eps_abs = as_positive("eps_abs", eps_abs)
        self.max_iter = int(as_positive("max_iter", max_iter))
        if bounds_change and fixed_constraints:
            raise InvalidParameterError(
                "fixed_constraints", fixed_constraints, "False when bounds_change is True"
            )
        self.bounds_change = bounds_change
        self.fixed_constraints = fixed_constraints
        self._qps: dict[tuple[int, int, bool], Any] = {}

    def reset(self) -> None:
        """Drop the QP objects: the next solve of each shape starts cold, as a new one's."""
        self._qps.clear()

    def solve(
        self,
        H: Vector,
        g: Vector,
        C: Vector | None,
        l: Vector | None,
        u: Vector | None,
        l_box: Vector | None = None,
        u_box: Vector | None = None,
    ) -> Any:
        """Solve the QP; returns proxsuite's results (``x``, ``info.status``, ``info.iter``).

        The results object belongs to the reused QP and is overwritten by the next solve of
        the same shape: copy ``x`` to keep it. With ``fixed_constraints`` the constraint
        arguments are read at the first solve of each shape only.

        Args:
            H: Hessian, symmetric positive semidefinite, shape (n, n).
            g: Linear term, shape (n,).
            C: Inequality matrix, shape (n_in, n), or None without inequalities.
            l: Lower bounds of ``C x``, shape (n_in,) (``-INFINITY`` for none).
            u: Upper bounds of ``C x``, shape (n_in,) (``INFINITY`` for none).
            l_box: Lower bounds of x, shape (n,), or None without box constraints.
            u_box: Upper bounds of x, shape (n,); given together with ``l_box``.
        """
        box = l_box is not None
        key = (g.size, 0 if C is None else C.shape[0], box)
        qp = self._qps.get(key)
        if qp is None:
            qp = proxsuite.proxqp.dense.QP(g.size, 0, key[1], box)
            qp.settings.eps_abs = self.eps_abs
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = self.max_iter
            qp.settings.verbose = False
            if box:
                qp.init(H, g, None, None, C, l, u, l_box, u_box)
            else:
                qp.init(H, g, None, None, C, l, u)
            qp.solve()
            # Only once a result exists: warm-starting from none crashes proxsuite 0.8.
            qp.settings.initial_guess = _GIVEN_START if self.bounds_change else _WARM_START
            self._qps[key] = qp
            return qp.results
        if self.fixed_constraints:
            qp.update(H, g)
        elif box:
            qp.update(H, g, None, None, C, l, u, l_box, u_box)
        else:
            qp.update(H, g, None, None, C, l, u)
        if not self.bounds_change:
            qp.solve()
            return qp.results
        qp.solve(np.array(qp.results.x), None, None)
        return qp.results
