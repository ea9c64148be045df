r"""Gaps, normal velocities, normal and tangential Jacobian rows of the constraints in one call.

:meth:`ConstraintSet.evaluate <ucontrol.contact.constraint_set.ConstraintSet.evaluate>` and
:meth:`~ucontrol.contact.constraint_set.ConstraintSet.jacobian` read Pinocchio's data one
contact at a time: a frame placement, a frame velocity and a frame Jacobian per contact, three
Python calls per contact, most of a Moreau–Jean step with a few contacts. For a robot of
revolute and prismatic joints, on a fixed base or a free-flyer root (a table on its feet, a
quadruped), whose constraints are point contacts against fixed planes and joint stops,
:class:`ConstraintRows` writes the same quantities as one casadi Function of (q, v), compiled
to C (:class:`~ucontrol.model.compiled_function.CompiledFunction`):

.. math::

    g_i = n_i \cdot p_{F_i}(q) - d_i, \qquad
    J_i = n_i^T \frac{\partial p_{F_i}}{\partial q}, \qquad u_i = J_i v

for contact i (frame origin :math:`p_{F_i}`, plane normal :math:`n_i`, offset
:math:`d_i = n_i \cdot p_0 + r_i`), and :math:`g = \sigma (q_j - b)`, :math:`J = \sigma e_j^T`
for a stop on coordinate j with bound b (:math:`\sigma = +1` lower, :math:`-1` upper); with a
free-flyer root, J is the derivative along the velocity v (the root's twist in its own
frame, Pinocchio's) rather than along q (:func:`_point_terms`). The
frame positions are those of :class:`~ucontrol.model.symbolic_model.SymbolicModel`; they equal
Pinocchio's to round-off (about 1e-16 m). The normals, offsets, signs and bounds are inputs, so
one library serves every plane and bound of a robot's contact frames and stop coordinates.

With friction, the same call gives the tangential rows of the frictional contacts,

.. math:: T_{ij} = t_{ij}^T \frac{\partial p_{F_i}}{\partial q} \quad (j = 1, \dots, c_i),

for the constant tangents :math:`t_{ij}` of a fixed plane, read from the same directions as
the reference rows (:attr:`~ucontrol.contact.ConstraintSet.point_directions`, an input of the
call). The reference adds a lever term :math:`\ell_{ij}^T J_{ang}` for a contact with a
radius (its contact point rolls): such sets give their normal rows alone here, and a step
reads their tangential rows from Pinocchio.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import InvalidParameterError
from ucontrol.model.robot_model import RobotModel

Vector = NDArray[np.float64]

#: The compiled call's inputs: the state, then the planes', stops' and tangents' constant terms.
_IN_NAMES = ["q", "v", "planes", "stops", "tangents"]
#: The active sets whose row selections a :class:`ConstraintRows` keeps at most.
_SELECTIONS = 64
#: The modules whose code writes the compiled call (part of its definition key).
_GENERATED_BY = (
    "ucontrol.contact.compiled_rows",
    "ucontrol.model.symbolic_model",
    "ucontrol.model.compiled_function",
)


class ConstraintRows:
    """The constraints of a :class:`ConstraintSet` as one compiled call (module docstring).

    Build it with :func:`compiled_rows`, which says whether a set qualifies.

    Args:
        constraints: Point contacts against fixed planes and joint stops of a robot of
            revolute and prismatic joints, on a fixed base or a free-flyer root.
        dynamics: Also compute M(q), h(q, v) and the energies in the same call, from
            :class:`~ucontrol.model.symbolic_model.SymbolicModel` (see :meth:`bind_dynamics`
            and :meth:`energies`).

    Raises:
        InvalidParameterError: The robot has a joint :class:`SymbolicModel` does not support.
    """

    def __init__(self, constraints: ConstraintSet, *, dynamics: bool = False) -> None:
        from ucontrol.model.compile_cache import definition_key
        from ucontrol.model.compiled_function import CompiledFunction

        robot = constraints.robot
        nv, n_c, n = robot.nv, constraints.n_contacts, constraints.size
        name = "constraint_rows_dynamics" if dynamics else "constraint_rows"
        counts = _tangent_counts(constraints)
        # What the Function is built from: casadi is imported only to build it (a cache miss).
        definition = definition_key(
            [name, robot.model.saveToString(), [c.frame for c in constraints.contacts], n_c, n,
             list(constraints.stop_coordinates), counts],
            _GENERATED_BY,
        )  # fmt: skip
        self.function = CompiledFunction.cached(
            name, definition, lambda: _rows_function(constraints, name, dynamics, counts)
        )
        self.dynamics = dynamics
        self._names = self.function.index_in, self.function.index_out  # by name
        index, out = self._names
        self._energies = self.function.output_buffer(out("energies")) if dynamics else None
        #: Tangential rows of the call (those of every frictional contact, in their order).
        self.tangential = sum(counts)
        # Each contact's first tangential row among all the rows (n + its offset).
        self._first_tangent = (n + np.cumsum(counts) - np.asarray(counts, dtype=int)).tolist()
        self._counts = counts
        self.use_constraints(constraints)  # the planes', stops' and tangents' terms
        self._n, self._nv = n, nv
        self._parts = (slice(0, n), slice(n, 2 * n), slice(2 * n, None))
        self._q, self._v = (
            self.function.input_view(index("q")),
            self.function.input_view(index("v")),
        )
        self._run = self.function.runner((index("q"), index("v")))  # writes q, v first
        self._out = self.function.output_buffer(out("rows"))
        self.last_rows: Vector | None = None  # the normal rows of the last call's values
        #: The normal, then tangential rows of the last call, shape (n + tangential, nv).
        self.last_contact_rows: Vector | None = None

    def use_constraints(self, constraints: ConstraintSet) -> None:
        """Compute the rows of ``constraints``: the set the call was built for, up to numbers.

        ``constraints`` may differ from that set in their numbers alone
        (:meth:`~ucontrol.contact.ConstraintSet.differs_in_numbers_only`): the planes', stops'
        and tangents' terms are inputs of the call, written here; nothing is built again.
        """
        index = self._names[0]
        # Column-major (4, n_c) and (2, n_s) inputs: the rows of the (n_c, 4) and (n_s, 2) terms.
        self.function.input_buffer(index("planes"))[:] = constraints.plane_terms.ravel()
        self.function.input_buffer(index("stops"))[:] = constraints.stop_terms.ravel()
        directions, counts = constraints.point_directions, self._counts
        # The tangents (k, 3), world coordinates: column-major (3, k) input.
        self._tangents = _read_only(
            np.concatenate([directions[i, 1 : 1 + c, :3] for i, c in enumerate(counts)])
            if self.tangential
            else np.zeros((0, 3))
        )
        self.function.input_buffer(index("tangents"))[:] = self._tangents.ravel()
        # The selections of the active sets met (contact_selection), with these tangents.
        self._selections: dict[tuple[int, ...], tuple[NDArray[np.intp], Vector]] = {}

    @property
    def compiled(self) -> bool:
        """Whether calls run compiled C (not casadi's virtual machine)."""
        return self.function.compiled

    def bind_dynamics(self, data: pin.Data) -> None:
        """Write M(q) and h(q, v) of each call into ``data.M`` and ``data.nle`` (``dynamics``).

        Those of ``pin.computeAllTerms`` to round-off (both triangles of M), so that readers
        of the data's M and h (a compiled step, a law) need not run it.
        """
        out = self._names[1]
        self.function.bind_output(out("M"), data.M)
        self.function.bind_output(out("h"), data.nle)

    def energies(self) -> tuple[float, float]:
        """Kinetic and potential energy in [J] at the last call's (q, v) (``dynamics``)."""
        assert self._energies is not None
        kinetic, potential = self._energies.tolist()
        return kinetic, potential

    def __call__(self, q: Vector, v: Vector) -> tuple[Vector, Vector, Vector]:
        """Gaps, normal velocities and rows at (q (nq,), v (nv,)), in new arrays.

        Returns:
            The gaps in [m] or [rad] (n,), the normal velocities ``J v`` in [m/s] or [rad/s]
            (n,) and the normal Jacobian rows J (n, nv), as a plain tuple (unpacked at once
            by its callers: a record type would be one object more per step).
        """
        self._run(q, v)
        out = self._out.copy()
        gaps, velocities, rows = self._parts
        self.last_contact_rows = contact_rows = out[rows].reshape(-1, self._nv)
        # (the normal rows alone: the same array, without a view more)
        self.last_rows = contact_rows[: self._n] if self.tangential else contact_rows
        return out[gaps], out[velocities], self.last_rows

    def buffers(self) -> tuple[Vector, Vector, Vector]:
        """The compiled call's inputs q (nq,), v (nv,) and its output, as the last call left them.

        The output holds the gaps (n,), the normal velocities (n,) and the rows, row by row:
        the normal ones (n nv,), then the tangential ones (:attr:`tangential` nv,).
        """
        return self._q, self._v, self._out

    def contact_selection(self, indices: NDArray[np.intp]) -> tuple[NDArray[np.intp], Vector]:
        """The rows of the active constraints ``indices`` (m,) among the call's n + k rows.

        Returns:
            Their normal rows' positions, then those of their tangential rows, in the order of
            ``indices`` (as :meth:`~ucontrol.contact.ConstraintSet.contact_rows` stacks
            them), shape (m + k_a,), and the map of the impulses of these rows (m + k_a,) to
            the world friction impulse of every constraint (n, 3), row by row: the sum of
            each tangential impulse times its tangent (constant on a fixed plane), shape
            (3 n, m + k_a) (read-only). Kept for each active set met (a few sets of feet).
        """
        key = tuple(indices.tolist())
        selection = self._selections.get(key)
        if selection is None:
            if len(self._selections) >= _SELECTIONS:
                self._selections.clear()
            counts, first, m = self._counts, self._first_tangent, len(key)
            owners = [i for i in key for _ in range(counts[i])]
            tangential = [first[i] + j for i in key for j in range(counts[i])]
            selected = np.array(key + tuple(tangential), dtype=np.intp)
            friction_map = np.zeros((self._n, 3, selected.size))
            for column, (i, row) in enumerate(zip(owners, tangential, strict=True)):
                friction_map[i, :, m + column] = self._tangents[row - self._n]
            selection = selected, _read_only(friction_map.reshape(3 * self._n, -1))
            self._selections[key] = selection
        return selection


def _rows_function(constraints: ConstraintSet, name: str, dynamics: bool, counts: list[int]) -> Any:
    """The casadi Function ``name`` of :class:`ConstraintRows` (its module docstring).

    ``counts``: the tangential rows of each point contact (:func:`_tangent_counts`).

    Raises:
        InvalidParameterError: The robot has a joint :class:`SymbolicModel` does not support.
    """
    import casadi as ca  # imported only for the sets that qualify, and only to build

    robot = constraints.robot
    nq, nv, n_c, n = robot.nq, robot.nv, constraints.n_contacts, constraints.size
    q, v = ca.SX.sym("q", nq), ca.SX.sym("v", nv)
    planes = ca.SX.sym("planes", 4, n_c)  # columns (normal, offset)
    stops = ca.SX.sym("stops", 2, n - n_c)  # columns (sign, bound)
    tangents = ca.SX.sym("tangents", 3, sum(counts))  # columns: each tangential row's t
    points = _point_terms(robot, q)
    gaps, rows = [], []
    tangent_rows: list[Any] = []  # each frictional contact's, in order
    for i, contact in enumerate(constraints.contacts):
        position, jacobian = points(contact.frame)
        normal = planes[:3, i]
        gaps.append(ca.dot(normal, position) - planes[3, i])
        rows.append(normal.T @ jacobian)
        for _ in range(counts[i]):  # (no lever: _tangent_counts)
            tangent_rows.append(tangents[:, len(tangent_rows)].T @ jacobian)
    for k, (index_q, index_v) in enumerate(constraints.stop_coordinates):
        sign, bound = stops[0, k], stops[1, k]
        gaps.append(sign * (q[index_q] - bound))
        row = ca.SX.zeros(1, nv)
        row[index_v] = sign
        rows.append(row)
    J = ca.vertcat(*rows)
    rows_t = ca.vertcat(J, *tangent_rows).T
    outputs = [ca.vertcat(ca.vertcat(*gaps), J @ v, ca.vec(rows_t))]  # J, then T, row by row
    if dynamics:  # M, h, and the energies (T, V)
        from ucontrol.model.symbolic_model import SymbolicModel

        model = SymbolicModel(robot)
        M = model.mass_matrix(q)
        energies = ca.vertcat(0.5 * ca.dot(v, M @ v), model.potential_energy(q))
        outputs += [M, model.nonlinear_effects(q, v), energies]
    out_names = ["rows", "M", "h", "energies"][: len(outputs)]
    return ca.Function(name, [q, v, planes, stops, tangents], outputs, _IN_NAMES, out_names)


def _tangent_counts(constraints: ConstraintSet) -> list[int]:
    """The tangential rows of each point contact in the compiled call, as Python ints.

    Those of :attr:`~ucontrol.contact.ConstraintSet.tangent_count` when no frictional
    contact has a lever (a radius), else none (module docstring).
    """
    directions = constraints.point_directions
    counts = constraints.tangent_count[: len(constraints.contacts)].tolist()
    if np.any(directions[:, 1:, 3:]):  # a rolling contact point: the Pinocchio rows
        return [0] * len(counts)
    return [int(c) for c in counts]


def _read_only(array: Vector) -> Vector:
    """``array``, made read-only (shared by the calls that read it)."""
    array.flags.writeable = False
    return array


def _point_terms(robot: RobotModel, q: Any) -> Callable[[str], tuple[Any, Any]]:
    r"""``frame -> (p, J)``: a frame origin's world position (3,) and its Jacobian (3, nv).

    For a fixed base, :math:`J = \partial p / \partial q`. With a free-flyer root (position
    :math:`p_b`, unit quaternion of rotation :math:`R`, its velocity (linear, angular) in its
    own frame, as Pinocchio's), the frame's position in the root's frame :math:`r(q_r)` is
    that of the fixed-base model of the other joints, and

    .. math:: p = p_b + R\, r, \qquad
              J = R \begin{pmatrix} I & -[r]_\times & \partial r / \partial q_r \end{pmatrix},

    both then moved by the root joint's placement in the world (the identity in a URDF's).

    Raises:
        InvalidParameterError: A joint :class:`SymbolicModel` does not support.
    """
    import casadi as ca

    from ucontrol.model.symbolic_model import SymbolicModel

    model = robot.model
    if robot.nq == robot.nv or model.joints[1].shortname() != "JointModelFreeFlyer":
        fixed = SymbolicModel(robot)  # (raises on the joints it does not support)

        def fixed_point(frame: str) -> tuple[Any, Any]:
            position = fixed.frame_position(frame)(q)
            return position, ca.jacobian(position, q)

        return fixed_point
    # The other joints on a fixed base at the root joint's frame (locked at the identity).
    base = pin.Model(model)
    base.jointPlacements[1] = pin.SE3.Identity()
    reduced = SymbolicModel(RobotModel(pin.buildReducedModel(base, [1], pin.neutral(base))))
    q_rest = q[7:]
    rotation = _quaternion_rotation(q[3:7])
    placement = model.jointPlacements[1]  # of the root joint in the world, usually I

    def floating_point(frame: str) -> tuple[Any, Any]:
        r = reduced.frame_position(frame)(q_rest)  # [m], in the root joint's frame
        local = ca.horzcat(ca.SX.eye(3), -ca.skew(r), ca.jacobian(r, q_rest))
        position, jacobian = q[:3] + rotation @ r, rotation @ local
        if placement.isIdentity():
            return position, jacobian
        R0 = ca.DM(placement.rotation)
        return ca.DM(placement.translation) + R0 @ position, R0 @ jacobian

    return floating_point


def _quaternion_rotation(quaternion: Any) -> Any:
    """The rotation matrix (3, 3) of a unit quaternion (x, y, z, w), as Eigen writes it."""
    import casadi as ca

    x, y, z, w = (quaternion[k] for k in range(4))
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    return ca.vertcat(
        ca.horzcat(1.0 - (tyy + tzz), txy - twz, txz + twy),
        ca.horzcat(txy + twz, 1.0 - (txx + tzz), tyz - twx),
        ca.horzcat(txz - twy, tyz + twx, 1.0 - (txx + tyy)),
    )


def compiled_rows(constraints: ConstraintSet, *, dynamics: bool = False) -> ConstraintRows | None:
    """:class:`ConstraintRows` of ``constraints`` when they qualify and compile, else None.

    With ``dynamics``, for robots of at most
    :data:`~ucontrol.model.robot_model.SMALL_ROBOT_MAX_NV` joints, the rows also give the
    mass matrix, h and the energies (:meth:`ConstraintRows.bind_dynamics`), which their
    compiled symbolic terms compute faster than Pinocchio's recursive algorithms there.

    They qualify with at least one point contact and nothing but point contacts against fixed
    planes and joint stops, without bilateral constraints, on a robot of revolute
    and prismatic joints on a fixed base or a free-flyer root (whose rows carry no dynamics);
    they compile where a C compiler is present (and ``UCONTROL_NO_COMPILE`` is not set).
    Elsewhere the Pinocchio path of :class:`ConstraintSet` is faster than casadi's virtual
    machine, and is used.
    """
    from ucontrol.model.compiled_function import compilation_possible

    if not qualifies(constraints) or not compilation_possible():
        return None  # (casadi not even imported)
    from ucontrol.model.robot_model import SMALL_ROBOT_MAX_NV

    robot = constraints.robot
    try:
        rows = ConstraintRows(
            constraints,
            dynamics=dynamics and robot.nq == robot.nv and robot.nv <= SMALL_ROBOT_MAX_NV,
        )
    except InvalidParameterError:  # a spherical or a continuous joint
        return None
    return rows if rows.compiled else None


def qualifies(constraints: ConstraintSet) -> bool:
    """Whether ``constraints`` are plane point contacts (at least one) and stops alone.

    Without sphere–sphere contacts, collision pairs, moving surfaces, bilateral constraints or
    clearance joints; the robot's joints are checked when the rows are built. With friction,
    the rows also hold the tangential ones, unless a frictional contact has a radius (module
    docstring): a frictional step then reads its tangential rows from Pinocchio
    (:meth:`~ucontrol.contact.ConstraintSet.contact_rows`).
    """
    return bool(
        constraints.contacts
        and not constraints.sphere_contacts
        and constraints.collision is None
        and constraints.bilateral is None
        and not constraints.time_dependent
        and not constraints.clearances
    )
