r"""The basin of attraction of a gait, probed by iterating its stride map from many starts.

A start :math:`z_0` (in the heel-strike chart of :func:`~ucontrol.analysis.gait.find_gait`) is
in the gait's basin when the strides :math:`z_{k+1} = P(z_k)` reach the gait,
:math:`\|z_k - z^*\| \le \text{tol}\,\max(1, \|z^*\|)`, within ``max_strides``. Each start ends
one of three ways (:class:`BasinOutcome`):

- ``"gait"``: it reached the gait (after ``strides`` strides);
- ``"fall"``: a stride failed (:class:`~ucontrol.exceptions.StrideError`: the walker fell back,
  lifted off, slipped, or no foot struck in time);
- ``"unsettled"``: ``max_strides`` strides without reaching the gait (another gait, a slow
  approach, a walker that steps backwards and forwards).

:func:`probe_basin` runs the starts one by one, or as a campaign on a Dask cluster
(``client``: a ``distributed.Client``, e.g. of a ``LocalCluster`` or of a real cluster's
scheduler), and returns a pandas table with one row per start.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ucontrol._validation import as_positive
from ucontrol.analysis.gait import Walker
from ucontrol.exceptions import InvalidParameterError, StrideError

if TYPE_CHECKING:
    import pandas as pd

Vector = NDArray[np.float64]
#: The ways a start can end, in the order of the table's categories.
OUTCOMES = ("gait", "fall", "unsettled")


@dataclass(frozen=True)
class BasinOutcome:
    """How the strides from one start ended.

    Attributes:
        z0: The start, shape (k,).
        outcome: ``"gait"``, ``"fall"`` or ``"unsettled"`` (module docstring).
        strides: Strides taken (to reach the gait, to the failing one included, or all).
        distance: ‖z - z*‖ at the last state reached.
        reason: The stride error's message for a fall, else "".
    """

    z0: Vector
    outcome: str
    strides: int
    distance: float
    reason: str = ""


def stride_outcome(
    walker: Walker,
    to_state: Callable[[Vector], tuple[Vector, Vector]],
    from_state: Callable[[Vector, Vector], Vector],
    gait: Vector,
    z0: Vector,
    *,
    max_strides: int = 50,
    tol: float = 1e-6,
) -> BasinOutcome:
    """Iterate the stride map from ``z0`` until it reaches ``gait``, fails, or runs out.

    Args:
        walker: Anything with ``stride(q, v)`` (a stance flow, the simplest walker).
        to_state: The post-strike state (q, v) of chart coordinates z (k,).
        from_state: The chart coordinates (k,) of a post-strike state.
        gait: The gait's fixed point z*, shape (k,).
        z0: The start, shape (k,).
        max_strides: Strides at most, >= 1.
        tol: Distance to the gait, relative to max(1, ‖z*‖), that counts as reached.

    Raises:
        InvalidParameterError: ``max_strides`` < 1, ``tol`` <= 0, or ``z0`` and ``gait`` of
            different shapes.
    """
    if not isinstance(max_strides, int) or max_strides < 1:
        raise InvalidParameterError("max_strides", max_strides, "an integer >= 1")
    tol = as_positive("tol", tol)
    target = np.asarray(gait, dtype=float)
    z = np.asarray(z0, dtype=float)
    if z.shape != target.shape:
        raise InvalidParameterError("z0", z.tolist(), f"shape {target.shape} (the gait's)")
    reach = tol * max(1.0, float(np.linalg.norm(target)))
    distance = float(np.linalg.norm(z - target))
    if distance <= reach:
        return BasinOutcome(z, "gait", 0, distance)
    for stride in range(1, max_strides + 1):
        try:
            q, v = to_state(z)
            result = walker.stride(q, v)
        except StrideError as error:
            return BasinOutcome(np.asarray(z0, dtype=float), "fall", stride, distance, str(error))
        z = np.asarray(from_state(result.q, result.v), dtype=float)
        distance = float(np.linalg.norm(z - target))
        if distance <= reach:
            return BasinOutcome(np.asarray(z0, dtype=float), "gait", stride, distance)
    return BasinOutcome(np.asarray(z0, dtype=float), "unsettled", max_strides, distance)


def probe_basin(
    walker: Walker,
    to_state: Callable[[Vector], tuple[Vector, Vector]],
    from_state: Callable[[Vector, Vector], Vector],
    gait: Vector,
    starts: Sequence[Vector] | NDArray[np.float64],
    *,
    max_strides: int = 50,
    tol: float = 1e-6,
    client: Any = None,
    progress: bool | None = None,
) -> pd.DataFrame:
    """:func:`stride_outcome` of every start: one row per start, in the order given.

    Args:
        walker: The walker (picklable when ``client`` is given).
        to_state: The chart's embedding (a module-level function or static method).
        from_state: The chart (likewise).
        gait: The gait's fixed point z*, shape (k,).
        starts: The starts, shape (N, k).
        max_strides: Strides at most per start.
        tol: Relative distance to the gait that counts as reached.
        client: A ``distributed.Client``: the starts run as its tasks; None: one by one here.
        progress: Show a progress bar (default: on a terminal).

    Returns:
        A table with columns ``z0_0 … z0_{k-1}``, ``outcome`` (categorical, :data:`OUTCOMES`),
        ``strides``, ``distance`` and ``reason``.
    """
    import pandas as pd
    from tqdm.auto import tqdm

    points = np.atleast_2d(np.asarray(starts, dtype=float))
    kwargs: dict[str, Any] = {"max_strides": max_strides, "tol": tol}
    bar = tqdm(total=len(points), disable=None if progress is None else not progress, unit="start")
    outcomes: list[BasinOutcome] = []
    if client is None:
        for z0 in points:
            outcomes.append(stride_outcome(walker, to_state, from_state, gait, z0, **kwargs))
            bar.update()
    else:
        from distributed import as_completed

        futures = [
            client.submit(
                stride_outcome, walker, to_state, from_state, gait, z0, pure=False, **kwargs
            )
            for z0 in points
        ]
        for _ in as_completed(futures):
            bar.update()
        outcomes = client.gather(futures)
    bar.close()
    table = pd.DataFrame(
        {f"z0_{i}": points[:, i] for i in range(points.shape[1])}
        | {
            "outcome": pd.Categorical([o.outcome for o in outcomes], categories=OUTCOMES),
            "strides": [o.strides for o in outcomes],
            "distance": [o.distance for o in outcomes],
            "reason": [o.reason for o in outcomes],
        }
    )
    return table
