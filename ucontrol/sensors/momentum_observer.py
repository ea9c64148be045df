r"""The generalized-momentum observer: external forces and impacts from q and the torque sent.

De Luca's residual (A. De Luca, R. Mattone, "Sensorless robot collision detection and hybrid
force/motion control", ICRA 2005; S. Haddadin, A. De Luca, A. Albu-Schäffer, "Robot collisions:
a survey on detection, isolation, and identification", IEEE T-RO 33(6), 2017, §IV). With the
generalized momentum :math:`p = M(q)\dot q`, the dynamics
:math:`M \ddot q + C \dot q + g = \tau + \tau_{ext}` read
:math:`\dot p = \tau + C(q, \dot q)^T \dot q - g(q) + \tau_{ext}` (since
:math:`\dot M = C + C^T`), and the residual

.. math::

    r(t) = K_o \Big[p(t) - p(0) - \int_0^t \big(\tau + C^T \dot q - g + r\big)\, ds\Big]

obeys :math:`\dot r = K_o (\tau_{ext} - r)`: a first-order low-pass image of the external
generalized force :math:`\tau_{ext} = J_c^T \lambda` with bandwidth :math:`K_o` [1/s]. Only
the measured state and the torque sent to the joints enter; no acceleration, no inverse of M.

Sampled at the control period :math:`T`, with :math:`\beta = C^T \dot q - g` integrated by the
trapezoid rule (the torque is held over the period, so its integral is exact) and :math:`r`
implicitly (backward Euler):

.. math::

    r_k = \frac{K_o}{1 + K_o T} \Big[p_k - p_0 - I_{k-1}
          - T\big(\tau_{k-1} + \tfrac{1}{2}(\beta_{k-1} + \beta_k)\big)\Big],\qquad
    I_k = I_{k-1} + T\big(\tau_{k-1} + \tfrac{1}{2}(\beta_{k-1} + \beta_k) + r_k\big).

For a constant :math:`\tau_{ext}` this gives :math:`r_k = (1 - (1 + K_o T)^{-k})\,\tau_{ext}`,
the backward-Euler image of :math:`(1 - e^{-K_o t})\,\tau_{ext}`, stable for every
:math:`K_o T` (the explicit form diverges beyond :math:`K_o T = 2`).

The change of :math:`r` over a period is its decay toward zero plus the image of the period's
external impulse :math:`T \bar\tau_{ext,k} = p_k - p_{k-1} - T(\tau_{k-1} +
\tfrac{1}{2}(\beta_{k-1} + \beta_k))`:

.. math::

    j_k = r_k - \frac{r_{k-1}}{1 + K_o T} = \frac{K_o T}{1 + K_o T}\, \bar\tau_{ext,k}.

An impulse :math:`J_c^T P` within the period gives :math:`j_k = K_o J_c^T P / (1 + K_o T)`,
a persistent force :math:`\lambda` only :math:`K_o T J_c^T \lambda / (1 + K_o T)`: an impact
is declared when :math:`\|j_k\|` exceeds a threshold [N m]. (The plain jump
:math:`\|r_k - r_{k-1}\|` also holds the decay, :math:`K_o T \|r_{k-1}\| / (1 + K_o T)`,
which after an impact of the two-link arm stays above 1 N m for 14 periods: measured in
``tests/test_momentum_observer.py``.)

The contact forces of the constraints believed closed are the least-squares solution of
:math:`J_c^T \hat\lambda = r`.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_positive, as_vector

Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]


class MomentumObserver:
    """The residual of a robot model, updated once per control period.

    Args:
        model: The Pinocchio model the observer believes (the controller's, not the plant's).
        gain: Bandwidth K_o in [1/s], > 0.
        period: Sampling period T in [s], > 0.
        threshold: Impact threshold on the residual's jump over one period in [N m], > 0.

    Raises:
        InvalidParameterError: ``gain``, ``period`` or ``threshold`` is not a number > 0.
    """

    def __init__(self, model: pin.Model, gain: float, period: float, threshold: float) -> None:
        gain, period = as_positive("gain", gain), as_positive("period", period)
        self.model, self.gain, self.period = model, gain, period
        self.threshold = as_positive("threshold", threshold)
        self._data = model.createData()
        self._scale = gain / (1.0 + gain * period)  # [1/s]
        nv = model.nv
        self.residual = np.zeros(nv)  # r_k [N m]
        self.jump = 0.0  # ||j_k||, the period's external impulse seen in r [N m]
        self.impact = False
        self._p0: Vector | None = None
        self._integral = np.zeros(nv)  # I_k [N m s]
        self._beta = np.zeros(nv)  # beta at the last sample [N m]

    def update(self, q: Vector, v: Vector, tau: Vector) -> Vector:
        """The residual at the new sample, shape (nv,) in [N m].

        The first call sets p(0) and returns zero.

        Args:
            q: Measured configuration, shape (nq,).
            v: Velocity estimate, shape (nv,) in [rad/s] or [m/s].
            tau: Mean generalized torque applied over the period that ends now (the held
                input), shape (nv,) in [N m] (unused on the first call).

        Raises:
            ShapeError: ``tau`` is not of shape (nv,).
            NonFiniteValueError: ``tau`` holds NaN or infinity.
        """
        model, data, T = self.model, self._data, self.period
        tau = as_vector("tau", tau, model.nv)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
        p = M @ v  # [N m s]
        C = pin.computeCoriolisMatrix(model, data, q, v)
        beta = C.T @ v - pin.computeGeneralizedGravity(model, data, q)  # [N m]
        if self._p0 is None:
            self._p0, self._beta = p, beta
            return self.residual.copy()
        flow = tau + 0.5 * (self._beta + beta)  # [N m] mean over the period, r aside
        r = self._scale * (p - self._p0 - self._integral - T * flow)
        self._integral += T * (flow + r)
        self.jump = float(np.linalg.norm(r - self.residual / (1.0 + self.gain * T)))
        self.impact = self.jump > self.threshold
        self.residual, self._beta = r, beta
        return r.copy()

    def contact_forces(self, J: Matrix) -> Vector:
        r"""Least-squares forces :math:`\hat\lambda` of :math:`J^T \hat\lambda = r`, shape (m,).

        Args:
            J: Normal Jacobian rows of the constraints believed closed, shape (m, nv).
        """
        if J.shape[0] == 0:
            return np.zeros(0)
        forces, *_ = np.linalg.lstsq(J.T, self.residual, rcond=None)
        return np.asarray(forces, dtype=float)
