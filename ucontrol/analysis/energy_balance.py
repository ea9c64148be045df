"""Energy balance of a run: the work done by the actuators since the start."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ucontrol.log import Log


def actuator_work(log: Log) -> NDArray[np.float64]:
    r"""Work of the actuators from ``t[0]`` to each sample, in [J], shape (N,).

    Over step k the torque :math:`u_k` (zero-order hold) works
    :math:`h\, u_k \cdot ((1 - \theta) v_k + \theta v_{k+1})` on the actuated coordinates, with
    the θ of the log's ``theta`` metadata (1/2 if absent): the velocity Moreau–Jean moves the
    configuration with. Without impacts or friction, ``energy - actuator_work`` stays at its
    initial value (to the scheme's accuracy); every impact can only lower it.
    """
    if len(log) < 2:
        return np.zeros(len(log))
    theta = float(log.metadata.get("theta", 0.5))
    actuated = np.asarray(log.metadata.get("actuated", []), dtype=int)
    v_mid = ((1.0 - theta) * log.v[:-1] + theta * log.v[1:])[:, actuated]  # [rad/s]
    power = np.einsum("ij,ij->i", log.u[:-1], v_mid)  # [W]
    return np.concatenate([[0.0], np.cumsum(power * np.diff(log.t))])
