r"""Moreau–Jean time-stepping (event-capturing θ-scheme), with or without Coulomb friction.

One step from :math:`(q_k, v_k)` with step :math:`h` and :math:`\theta \in [1/2, 1]`:

1. free velocity :math:`v_\text{free} = v_k + h M^{-1}(\tau - h(q_k, v_k))`;
2. active set by prediction: :math:`a \in I` iff :math:`g_a + \gamma h u_a \le 0`
   (:math:`\gamma = 1/2`), or :math:`\le \varepsilon_p + h u_p` for a constraint that carried
   an impulse in the previous step (persistence, below);
3. Signorini–Newton at velocity level on :math:`I`:
   :math:`0 \le u_a(v_{k+1}) + e_a u_a(v_k) \perp P_a \ge 0`, solved as a QP in the impulses,
   :math:`v_{k+1} = v_\text{free} + M^{-1} J_I^T P`;
4. :math:`q_{k+1} = q_k \oplus h((1-\theta) v_k + \theta v_{k+1})`.

Every matrix is evaluated at step k. The scheme is of order one, captures impacts without
locating them, and enforces Newton's law exactly at every impact.

**Persistent contacts.** A contact held while sliding (a tip pressed along a wall) drifts off
its surface by O(h²) per step: the velocity is constrained with :math:`J(q_k)`, the position
advanced with :math:`\theta`-averaged velocities. With the rule of step 2 alone the contact
then leaves the active set every other step, and its impulse alternates between 0 and twice
the force it carries. A constraint with an impulse in the previous step therefore stays active
while its predicted gap is at most the release gap :math:`\varepsilon_p + h u_p`
(``persistence_tolerance``, 1 µm by default, and ``persistence_speed``, 0.1 m/s), and with a
positive gap :math:`g_a` its condition is :math:`0 \le u_a^+ + g_a/h \perp P_a`: it may
approach its surface at the speed that closes the gap in one step, not faster, and never
adheres. The integrator keeps that memory between steps (:meth:`MoreauJean.reset` forgets it).

The band :math:`h u_p` scales with the drift. A contact held on a curved path (a spoke
pivoting on its foot, a foot on a turning body) has its velocity constrained with
:math:`J(q_k)`, so at :math:`q_{k+1}` its normal velocity is :math:`O(h)` away from the surface
(:math:`h\,\dot q^T \nabla^2 g\,\dot q`, the centripetal term :math:`\omega^2 l h`) and its
gap grows by :math:`O(h^2)` a step: 1.7 µm at h = 1 ms on the rimless wheel's stance spoke.
With :math:`\varepsilon_p` alone such a contact was released whenever its gap passed 1 µm,
fell back within a step, and its re-closure was an impact: 223 "impacts" in 6 s of the wheel
for 8 strikes. The band holds it while that normal velocity, :math:`O(h)`, is below
:math:`u_p`. Keeping a held row costs nothing physically: its condition above only acts on a
free motion that would cross the surface within the step, and a contact that separates gets
no impulse and leaves the memory at once.

**Impacts.** A step's :attr:`StepOutcome.impacts` are the constraints that get an impulse and
close at its start faster than
:data:`~ucontrol.integrators.step_stages.IMPACT_VELOCITY_THRESHOLD`, or faster than
:data:`~ucontrol.integrators.step_stages.HELD_IMPACT_VELOCITY` when held by the previous step
(:func:`~ucontrol.integrators.step_stages.is_impact`), the rule by which
:func:`~ucontrol.analysis.impacts.impact_mask` reads a log (a held contact closing its drift is
not an impact).

**Contacts that may not close.** A point contact with a scuffing rule (``closes_ahead_of``:
a walker's swing foot passes through the ground until its hip is past the stance foot) is left
out of the active set while :meth:`~ucontrol.contact.ConstraintSet.closure_barred` bars it,
unless the last step held it (:meth:`MoreauJean._barred`): one forward kinematics pass a step,
in the scenes that declare such a rule only.

**Contacts closed at the start.** A run starts with no memory, so a contact placed on its
surface with a gap that rounds to a tiny positive value (:math:`+10^{-18}` m from the trigonometry
of an incline) would be left out of the first step: the body falls freely for one step, lands,
and a block put flat on an incline tilts by :math:`6.2\cdot10^{-5}` rad. The first step of a run
(after construction or :meth:`MoreauJean.reset`) therefore treats every constraint whose gap is
at most :math:`\varepsilon_0` (``START_GAP_TOLERANCE``, 1 nm, the initial penetration
:func:`~ucontrol.simulate.simulate` admits) and whose predicted gap would leave it out as held
in the previous step: it is active with the condition :math:`0 \le u_a^+ + g_a/h \perp P_a`
above (no restitution; an approach slower than :math:`\varepsilon_0/(\gamma h)` is the only
one it changes, which is 2 µm/s at h = 1 ms).

**Flexible joints.** With :class:`~ucontrol.model.FlexibleJoints` the state holds the motor
coordinates after the link ones and the joint springs (stiffness matrix :math:`K_q`) and
dampers (:math:`C_v`) are treated θ-implicitly (DESIGN §4.1): with
:math:`W = \operatorname{diag}(M(q_k), B) + h\theta C_v + h^2\theta^2 K_q`,

.. math:: v_\text{free} = v_k + W^{-1} h \big(F_k - h\theta K_q v_k\big),

:math:`F_k` holding the spring and damper forces at step k; the impulses act through
:math:`W^{-1}` on the link coordinates only. For θ = 1/2 the springs' energy is kept exactly
(trapezoidal rule), for θ = 1 it is dissipated; both stay bounded at any :math:`\sqrt{K/B}\,h`,
where an explicit update diverges once it exceeds 2.

**Midpoint variant** (``midpoint=True``). Step 1 above evaluates M, gravity and the Coriolis
forces at :math:`(q_k, v_k)`: between impacts the step is then of order one, and the energy of
a smooth motion drifts at O(h) even with θ = 1/2. The variant evaluates M and gravity at
:math:`q_{k+1/2} = q_k \oplus \tfrac h2 v_k` and the Coriolis forces as the symmetric bilinear
form :math:`\Gamma(q_{k+1/2}; v_k, v^*)` (:math:`\Gamma(q; v, v) = C(q, v)v`), :math:`v^*`
being the velocity of a first solve with :math:`\Gamma(v_k, v_k)`. With bilateral constraints
their rows enter step 3 at the midpoint too,

.. math:: J_b(q_{k+1/2})\, v_{k+1} = \big(J_b(q_k) - J_b(q_{k+1/2})\big)\, v_k,

the impulses acting along :math:`J_b(q_{k+1/2})^T` (the direction of the constraint forces over
the step) and the condition being :math:`J_b(q_{k+1}) v_{k+1} = 0` to :math:`O(h^2)`
(:math:`J_b(q_{k+1}) \approx 2 J_b(q_{k+1/2}) - J_b(q_k)`) with a symmetric :math:`D`; and
:math:`v^*` is held by these rows (:meth:`MoreauJean._bilateral_correction`), so that it is
within :math:`O(h^2)` of :math:`v_{k+1}`. Both are needed: rows at :math:`q_k`
(:math:`J_b(q_k) v_{k+1} = 0`) or a free :math:`v^*`, which misses the closures' impulses by
O(h), leave the step of order one. With θ = 1/2 the step is then of second order between
impacts: observed orders 2.00 on the two-link arm before its first impact and 1.96 on the
four-bar of ``robots/four_bar.toml`` (1.0 and 1.09 without the variant; with rows at
:math:`q_k` and a free :math:`v^*` the four-bar's error was nine times the default step's,
0.48 against 0.055 rad over 1 s at h = 1 ms), experiments/midpoint_order.py. Gaps, the active
set and the unilateral rows stay at :math:`q_k` and :math:`v^*` ignores their impulses: the
scheme is of order one through impacts, and nothing makes it of order two while a unilateral
contact is held.

Newton's law uses :math:`e_a` for closing constraints only (:math:`u_a < -u_\text{th}`, the
``restitution_threshold``, 0 by default); separating or persistent ones get :math:`e_a = 0`.
On simultaneous impacts this generalized Newton law can add energy: with unequal restitutions,
near singular configurations where constraint rows are almost dependent, or when a body joins
an impacting group within the step (a column of beads: a bead rebounding on a resting stack
catches the one above it, and the group leaves at :math:`e` times the speed of the first). The
energy the impulses add to the scheme's discrete energy :math:`T + V` over the step is

.. math:: G = \tfrac12 P^T(u_\text{free} + u^+) - \theta P^T (u_\text{free} - u_k),

the kinetic part and the work of the step's smooth forces over the displacement the impulses
cause (for θ = 1/2, :math:`\tfrac12 P^T (u_k + u^+)`); a step with :math:`G > 0` is redone with
the plastic law (e = 0), flagged in :attr:`StepOutcome.plastic`. (The kinetic part alone misses
the beads' case: it is measured from :math:`v_\text{free}`, which holds a step of gravity.)
The guard checks steps with restitution only: with θ < 1 a contact in the active set while
separating at :math:`t_k` (:math:`u_k > 0`, it penetrates) that the impulse holds at
:math:`u^+ = 0` gains :math:`(1-\theta) P u_k`. On rigid robots :math:`u_k` is then at the
level of the active-set flicker and the gain negligible; with very stiff joint springs
(:math:`\omega h \gg 1`) the tip's velocity can reverse within the step and the gain become
visible (docs/flexible.md): θ = 1 has none.

**Friction.** Active contacts with a friction coefficient add their tangential rows
(:meth:`~ucontrol.contact.ConstraintSet.tangent_rows`) below the normal ones; step 3 is then
Coulomb's law at velocity level with Newton's restitution on the normal components only
(:class:`~ucontrol.solvers.coulomb_problem.CoulombProblem`), solved by the friction solver
(default :class:`~ucontrol.solvers.ProxsuiteCoulombSolver`, built only when the constraints
have friction). The energy guard applies unchanged, over normal and tangential rows (with e = 0
Coulomb's impulses dissipate: :math:`P^T u^+ = -\mu P_n \|u_t^+\| + P_t \cdot u_t^+ \le 0`).

**Friction in joints** (:class:`~ucontrol.model.joint_friction.JointFriction`, on the link
coordinates). Viscous friction :math:`-D v` acts on the θ-averaged velocity the positions
advance with, :math:`M(v^+ - v_k) = h(F_k - D((1-\theta) v_k + \theta v^+)) + \dots`, hence
:math:`W = M + h\theta D` and :math:`F_k - D v_k` in step 1 (with θ = 1/2 the step dissipates
exactly :math:`h D \bar v^2`, :math:`\bar v = (v_k + v^+)/2`). Coulomb friction
:math:`P_{f,j} \in -h F_{c,j} \operatorname{Sgn}(v_j^+)` adds one row :math:`e_j^T` per joint
after the contacts' rows; each is solved as a planar contact of the Coulomb problem with
:math:`\mu = 1` whose normal impulse is pinned at :math:`h F_{c,j}` by an auxiliary row
decoupled from the others (:meth:`MoreauJean._solve_with_joints`), so that contacts and joints
are one problem for the friction solver, built whenever a joint has Coulomb friction. The
step's :attr:`StepOutcome.solution` then has the joint rows last (impulses in [N m s]).

**Moving surfaces.** Constraints against surfaces with a prescribed motion
(:attr:`~ucontrol.contact.ConstraintSet.time_dependent`) have relative velocities
:math:`u = J v + \partial g/\partial t`: Signorini and Newton's law hold on them,
:math:`0 \le u_a(v_{k+1}, t_{k+1}) + e_a u_a(v_k, t_k) \perp P_a \ge 0`, so
:math:`\partial g/\partial t` at :math:`t_{k+1}` enters :math:`b` (and the tangential
:math:`-t \cdot \dot x` its friction rows: a conveyor). :meth:`MoreauJean.evaluate` then
needs the time, which it keeps in the evaluation for :meth:`MoreauJean.step`. The energy guard
measures the impulses' work with the same relative velocities (energy in the surface's frame,
exact for a surface in uniform translation): a ball thrown up by a rising plate legitimately
gains energy.

**Bilateral constraints.** With loop closures or joint couplings
(:attr:`~ucontrol.contact.ConstraintSet.bilateral`, rows :math:`J_b`, residual :math:`h(q)`)
step 3 is a mixed problem: the bilateral rows are stacked last, their impulses free in sign,

.. math:: J_b v_{k+1} = 0, \qquad
          0 \le u_a(v_{k+1}) + e_a u_a(v_k) \perp P_a \ge 0 \; (a \in I),

solved as one QP with bounds on the unilateral impulses only
(:meth:`~ucontrol.solvers.ProxsuiteLCPSolver.solve_mixed`); with ``midpoint`` the bilateral
rows are those of the midpoint variant above (:meth:`MoreauJean._bilateral_rows`). The
position update of step 4
leaves an O(h²) residual :math:`h(q_{k+1})` per step, which would drift; the configuration is
therefore projected back onto :math:`h(q) = 0` after the step, by Gauss–Newton steps of least
(Euclidean) norm :math:`q \leftarrow q \ominus J_b^+ h(q)` until
:math:`\|h\|_\infty \le` :data:`BILATERAL_PROJECTION_TOLERANCE`; the velocity is left as the
solve gave it. A Baumgarte term :math:`J_b v_{k+1} = -h(q_k)/h` instead (measured on the
four-bar of ``tests/integrators/test_bilateral.py``) kept the residual at 6e-5 m but raised
the energy error and the phase error twentyfold at h = 1e-3.
Dependent rows (a planar mechanism's out-of-plane closure row, a closure declared twice) make
:math:`D` singular; the proximal QP and a least-squares polish keep the minimum-norm impulses.
Bilateral constraints need the proxsuite solver; the energy guard measures the other rows'
impulses only (and, as everywhere, runs under the ``"closing"`` law alone). With friction
(active contacts with a friction coefficient, or Coulomb joints) the bilateral rows come
after the contacts' normal and tangential rows and the joints' rows, and the step solves the
mixed Coulomb problem

.. math:: J_b v_{k+1} = 0 \;(P_b \text{ free}), \qquad
          K_a \ni P_a \perp \hat u_a \in K_a^* \; (a \in I),

(:class:`~ucontrol.solvers.coulomb_problem.CoulombProblem` with ``equalities``) by the Tresca
fixed point, each Tresca QP leaving the bilateral impulses unbounded
(:class:`~ucontrol.solvers.ProxsuiteCoulombSolver`, the only friction solver accepted with
bilateral constraints); the drift is projected away as above.

**Stages and paths.** A step is a list of named stages (:meth:`MoreauJean.step`): free
velocity, active set, impact law (the offsets of the problem), contact problem with the energy
guard, position update (and projection). What a step leaves to the next — the activation of
the held constraints and whether the run has started — is one object,
:attr:`MoreauJean.memory` (:class:`~ucontrol.integrators.step_stages.StepMemory`), and the
rules of the stages are pure functions of :mod:`~ucontrol.integrators.step_stages`. Unilateral,
frictional, Coulomb-joint and bilateral rows are blocks of one contact stage. Each stage has
one readable reference (numpy, Pinocchio, LAPACK) and at most one generated fast path
(casadi, compiled to C): the constraint rows with M and h on small robots
(:mod:`~ucontrol.contact.compiled_rows`) and the free step with its one-row steps
(:mod:`~ucontrol.integrators.compiled_free_step`), which apply the same definitions of the
impact law, the predicted gaps and the energy guard on casadi's symbols. With friction the
compiled rows also give the tangential rows of the frictional contacts (without a radius), and
the free step, with plastic contacts, :math:`M^{-1} [J^T\ T^T]` and the Delassus matrix of all
the rows ("tangent rows"); elsewhere a contact step with tangential rows reads them from
Pinocchio's data and :math:`M^{-1} [J^T\ T^T]` from its Cholesky factor. The public switch
``compiled = False`` (or ``UCONTROL_NO_COMPILE=1``, or no C compiler) runs the references
alone; ``tests/test_paths_agree.py`` runs every shipped scene both ways and compares the logs
field by field (:attr:`MoreauJean.fast_paths` names the paths a step runs).

**Unsolved problems.** A solve whose residual stays above its solver's tolerance raises
:class:`~ucontrol.exceptions.ContactSolveError` (``on_unsolved = "raise"``), or issues a
:class:`~ucontrol.exceptions.ContactSolveWarning` carrying the residual and goes on with the
solver's best impulses (``on_unsolved = "warn"``); the residual is in every step's solution.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ucontrol._validation import as_float, as_in_interval, as_positive
from ucontrol.contact.compiled_rows import compiled_rows
from ucontrol.contact.constraint_set import ConstraintSet
from ucontrol.exceptions import ContactSolveError, ContactSolveWarning, InvalidParameterError
from ucontrol.integrators.step_stages import (
    NO_ACTIVE_ROW,
    NUMPY_OPS,
    SEVERAL_ACTIVE_ROWS,
    StepMemory,
    active_set,
    fresh_memory,
    gains_energy,
    impulse_energy_gain,
    is_impact,
    newton_offsets,
    next_memory,
    predicted_gaps,
    release_gap,
    theta_displacement,
)
from ucontrol.model.compiled_function import compilation_disabled
from ucontrol.model.flexible_joints import FlexibleJoints
from ucontrol.model.joint_friction import JointFriction
from ucontrol.model.robot_model import RobotModel
from ucontrol.plant import PlantEvaluation, StepOutcome, evaluate_plant, evaluate_rigid_rows
from ucontrol.solvers.contact_solution import ContactSolution
from ucontrol.solvers.contact_solver import CoulombSolver, LCPSolver
from ucontrol.solvers.coulomb_problem import CoulombProblem
from ucontrol.solvers.proxsuite_lcp import ProxsuiteLCPSolver

if TYPE_CHECKING:
    from ucontrol.integrators.compiled_free_step import CompiledFreeStep
    from ucontrol.model.root_subtrees import RootSubtrees

Vector = NDArray[np.float64]

#: Default predicted gap up to which a held constraint stays active, in [m] (or [rad]).
PERSISTENCE_TOLERANCE = 1e-6
#: Default speed in [m/s] (or [rad/s]) of the release band h u_p added to it (module docstring).
PERSISTENCE_SPEED = 0.1
#: Residual in [m] or [rad] at which the projection stops.
BILATERAL_PROJECTION_TOLERANCE = 1e-12
#: Gauss–Newton iterations of the projection at most.
BILATERAL_PROJECTION_ITERATIONS = 5
#: Whom Newton's law applies to: the closing constraints of the active set (the project's
#: rule, with the energy guard), or every active constraint, separating ones included, with no
#: guard (Siconos' MoreauJeanOSI, to reproduce its runs).
NEWTON_LAWS = ("closing", "siconos")
#: What a step does with a contact problem left above its residual tolerance.
ON_UNSOLVED = ("raise", "warn")


class MoreauJean:
    """Moreau–Jean integrator of a robot under unilateral constraints.

    The plant owns a private Pinocchio data buffer, so controllers may use the robot freely.
    Use :meth:`evaluate` at (q_k, v_k), then :meth:`step` with the generalized forces.

    Args:
        robot: The robot.
        constraints: Its unilateral constraints.
        dt: Time step h in [s].
        theta: θ of the position update, in [1/2, 1].
        solver: Frictionless contact solver; default a :class:`ProxsuiteLCPSolver`.
        friction_solver: Solver of the steps with friction, used only when ``constraints``
            have friction; default a :class:`~ucontrol.solvers.ProxsuiteCoulombSolver`.
        restitution_threshold: Closing speed in [m/s] (or [rad/s]) below which a contact is
            treated as persistent and gets e = 0; separating contacts always get e = 0.
            0 applies Newton's law to every closing contact.
        on_unsolved: ``"raise"`` a :class:`~ucontrol.exceptions.ContactSolveError` or
            ``"warn"`` (:class:`~ucontrol.exceptions.ContactSolveWarning`) when a contact
            solve ends above its solver's residual tolerance.
        flexible: Flexible joints of the robot: the state then holds their motor coordinates.
        midpoint: Evaluate the inertia, gravity and Coriolis forces at the midpoint (module
            docstring): second order between impacts, at about three more RNEA per step.
        persistence_tolerance: Predicted gap in [m] (or [rad]) up to which a constraint that
            carried an impulse in the previous step stays in the active set, with the band
            ``dt * persistence_speed`` added (module docstring); both 0 turn persistence off.
        persistence_speed: Speed :math:`u_p` in [m/s] (or [rad/s]) of the release band
            :math:`h u_p`: a held contact whose drift over a step changes its normal velocity
            by less stays active.
        newton_law: ``"closing"`` (default: restitution on closing constraints, energy guard)
            or ``"siconos"`` (restitution on every active constraint, no guard: Siconos'
            convention; with ``persistence_tolerance = 0`` it reproduces Siconos' runs).
        joint_friction: Viscous (θ-implicit) and Coulomb (set-valued, solved with the
            contacts) friction in the joints, on the link coordinates (module docstring).
        compiled: Run the generated fast paths of the stages where the step allows them and a
            C compiler is present (not with ``UCONTROL_NO_COMPILE`` set); False runs the
            readable reference stages alone (module docstring, "Paths").

    Attributes:
        friction_solver: The friction solver, or None for constraints without friction.
        memory: What the last step left to the next (:class:`StepMemory`).
        compiled: Whether the generated fast paths may run (the ``compiled`` argument).
    """

    name = "moreau_jean"
    gamma = 0.5  # active-set prediction horizon, in steps

    def __init__(
        self,
        robot: RobotModel,
        constraints: ConstraintSet,
        *,
        dt: float,
        theta: float = 0.5,
        solver: LCPSolver | None = None,
        friction_solver: CoulombSolver | None = None,
        restitution_threshold: float = 0.0,
        on_unsolved: str = "raise",
        flexible: FlexibleJoints | None = None,
        midpoint: bool = False,
        persistence_tolerance: float = PERSISTENCE_TOLERANCE,
        persistence_speed: float = PERSISTENCE_SPEED,
        newton_law: str = "closing",
        joint_friction: JointFriction | None = None,
        compiled: bool = True,
    ) -> None:
        if newton_law not in NEWTON_LAWS:
            raise InvalidParameterError("newton_law", newton_law, f"one of {NEWTON_LAWS}")
        self.newton_law = newton_law
        self.robot = robot
        self.flexible = flexible
        self.midpoint = bool(midpoint)
        # A second Pinocchio buffer for the midpoint's terms, only when asked for.
        self._midpoint_data = pin.Data(robot.model) if self.midpoint else None
        self._zero_acceleration = np.zeros(robot.nv)
        self.constraints = constraints
        self.dt = as_positive("dt", dt)
        self.theta = as_in_interval("theta", theta, 0.5, 1.0)
        self.solver: LCPSolver = solver if solver is not None else ProxsuiteLCPSolver()
        self.friction_solver: CoulombSolver | None = None
        self._set_joint_friction(joint_friction, robot, flexible, constraints)
        if constraints.has_friction or self._coulomb_rows is not None:
            self.friction_solver = (
                friction_solver if friction_solver is not None else _default_friction_solver()
            )
        if on_unsolved not in ON_UNSOLVED:
            raise InvalidParameterError("on_unsolved", on_unsolved, f"one of {ON_UNSOLVED}")
        self.on_unsolved = on_unsolved
        self.restitution_threshold = as_float("restitution_threshold", restitution_threshold)
        if self.restitution_threshold < 0.0:
            raise InvalidParameterError("restitution_threshold", restitution_threshold, ">= 0")
        self._model = robot.model
        # (idx_q, idx_v) of the joints integrated on R^3 x SO(3) or R^2 x SO(2) (_advance).
        kinds = [joint.shortname() for joint in robot.model.joints]
        self._free_flyers = [
            (joint.idx_q, joint.idx_v)
            for joint, kind in zip(robot.model.joints, kinds, strict=True)
            if kind == "JointModelFreeFlyer"
        ]
        self._planar_joints = [
            (joint.idx_q, joint.idx_v)
            for joint, kind in zip(robot.model.joints, kinds, strict=True)
            if kind == "JointModelPlanar"
        ]
        # nq = nv: every joint a vector space (only free-flyer, planar, spherical and
        # unbounded revolute joints have nq > nv), so q ⊕ dq = q + dq, as pin.integrate
        # computes it, motors included.
        self._vector_space = robot.nq == robot.nv
        self._data = pin.Data(robot.model)
        self._bilateral = constraints.bilateral
        self._projection_data = pin.Data(robot.model) if self._bilateral is not None else None
        self._has_contacts = constraints.n_contacts > 0 or self._bilateral is not None
        # Gaps, velocities and rows of plane contacts and stops in one compiled call, if possible.
        # (With the dynamics for small rigid robots: M and h written into the data; not with
        # friction, whose steps read the frame Jacobians of the data's kinematics.)
        self.compiled = bool(compiled)
        dynamics = flexible is None and not constraints.has_friction
        self._rows = compiled_rows(constraints, dynamics=dynamics) if compiled else None
        if self._rows is not None and self._rows.dynamics:
            self._rows.bind_dynamics(self._data)
        self._rigid_rows = self._rows if self.flexible is None else None
        self._shared_data = False  # whether evaluation_data was read (evaluate)
        # The frictionless solver started from the last step's active set (a fast path).
        self._guessing_solver = (
            self.solver
            if self.compiled
            and not compilation_disabled()
            and isinstance(self.solver, ProxsuiteLCPSolver)
            and self.solver.active_set_start
            else None
        )
        if self._bilateral is not None:
            if self.friction_solver is not None and not getattr(
                self.friction_solver, "bilateral_rows", False
            ):
                raise InvalidParameterError(
                    "friction_solver",
                    self.friction_solver.name,
                    "'proxsuite-tresca' with friction and bilateral constraints",
                )
            if not hasattr(self.solver, "solve_mixed"):
                raise InvalidParameterError(
                    "solver", self.solver.name, "'proxsuite' with bilateral constraints"
                )
        self._friction = constraints.has_friction
        self._plastic = not constraints.restitution.any()  # e = 0 everywhere: no rebound terms
        # Whether steps may need the energy guard: Newton's law on closing rows, with rebounds.
        self._guarded = newton_law == "closing" and not self._plastic
        self.persistence_tolerance = as_float("persistence_tolerance", persistence_tolerance)
        if self.persistence_tolerance < 0.0:
            raise InvalidParameterError("persistence_tolerance", persistence_tolerance, ">= 0")
        self.persistence_speed = as_float("persistence_speed", persistence_speed)
        if self.persistence_speed < 0.0:
            raise InvalidParameterError("persistence_speed", persistence_speed, ">= 0")
        # Predicted gap up to which a held constraint stays active [m] (or [rad]).
        self._release = release_gap(self.persistence_tolerance, self.persistence_speed, self.dt)
        #: What the last step left to the next (:class:`StepMemory`); :meth:`reset` renews it.
        self.memory = fresh_memory(constraints.size)
        # The memory after a step without impulses, and that step's outcome: shared, read-only.
        self._free_memory = StepMemory(_read_only(np.zeros(constraints.size)), False)
        # For each mask of rows met (bit i for constraint i): the active set, the rows'
        # indices and the memory after a step whose impulses are those rows' (_mask_terms).
        self._masks: dict[int, tuple[NDArray[np.bool_], NDArray[np.intp], StepMemory]] = {}
        # The active set of a one-row step of row i, and the memory after it when row i
        # carried an impulse, for each i.
        one_rows = [self._mask_terms(1 << i) for i in range(constraints.size)]
        self._row_actives = tuple(active for active, _, _ in one_rows)
        self._row_memories = tuple(memory for _, _, memory in one_rows)
        self._no_impulse = _read_only(np.zeros(constraints.size))
        # The active set of the steps with no active row, shared.
        self._none_active = _read_only(np.zeros(constraints.size, dtype=bool))
        self._no_friction_impulse = (
            _read_only(np.zeros((constraints.size, 3))) if constraints.has_friction else None
        )
        # Rows of the contact problem present at every step (a problem even with no contact).
        self._problem_rows = int(self._coulomb_rows is not None) + int(self._bilateral is not None)
        if flexible is not None:
            ht = self.dt * self.theta
            self._stiffness = flexible.coupling_matrix(flexible.stiffness)  # K_q
            implicit = ht * flexible.coupling_matrix(flexible.damping) + ht * ht * (
                self._stiffness
            )  # hθ C_v + h²θ² K_q
            nv = robot.nv
            implicit[nv:, nv:] += np.diag(flexible.motor_inertia)  # + B on the motors
            self._implicit_forces = implicit  # W without the links' M(q)
        self._closure_rules = constraints.has_closure_rules
        self._free_step = self._compiled_free_step()
        if self._free_step is not None and self._rigid_rows is not None:
            self._free_step.read_rows_of(self._rigid_rows)  # no copies of q, v and the rows

    def _set_joint_friction(
        self,
        friction: JointFriction | None,
        robot: RobotModel,
        flexible: FlexibleJoints | None,
        constraints: ConstraintSet,
    ) -> None:
        """Keep hθD (viscous) and the Coulomb joints' rows and bounds hF_c, if any."""
        self.joint_friction = friction
        self._viscous: Vector | None = None  # D on the link coordinates [N m s/rad]
        self._coulomb_rows: Vector | None = None  # selection rows S of the Coulomb joints
        self._coulomb_bounds = np.zeros(0)  # h F_c [N m s]
        if friction is None:
            return
        if friction.nv != robot.nv:
            raise InvalidParameterError(
                "joint_friction", f"{friction.nv} coordinates", f"{robot.nv} (the robot's nv)"
            )
        if friction.has_viscous:
            self._viscous = friction.viscous
        index = friction.coulomb_index
        if index.size:
            size = robot.nv if flexible is None else robot.nv + flexible.nf
            self._coulomb_rows = np.eye(size)[index]
            self._coulomb_bounds = self.dt * friction.coulomb[index]

    def reset(self) -> None:
        """Start a new run as a new integrator would: no step memory, no warm starts.

        Renews :attr:`memory`, resets the contact solvers, which start each solve from the
        last one's solution, and forgets that :attr:`evaluation_data` was read (a controller of
        the last run shared it; the next run's reads it again if it does).
        """
        self.memory = fresh_memory(self.constraints.size)
        self._shared_data = False
        self.solver.reset()
        if self.friction_solver is not None:
            self.friction_solver.reset()

    def use_constraints(self, constraints: ConstraintSet) -> bool:
        """Step against ``constraints`` from now on, if they differ from its own in numbers only.

        Restitutions (0 on the same constraints), friction coefficients, plane points and
        normals and stop bounds may differ
        (:meth:`~ucontrol.contact.ConstraintSet.differs_in_numbers_only`); the compiled calls
        take them as inputs, so nothing is built again, and the steps are then those of an
        integrator built with ``constraints``. A campaign worker gives its integrator this way
        to the runs that draw these numbers (:mod:`ucontrol.campaign.build_cache`). The step
        memory and the solvers' warm starts are kept: :meth:`reset` starts a new run.

        Returns:
            Whether the constraints were taken (False: they differ otherwise; nothing changed).
        """
        if not self.constraints.differs_in_numbers_only(constraints):
            return False
        self.constraints = constraints
        if self._rows is not None:
            self._rows.use_constraints(constraints)
        if self._free_step is not None:
            self._free_step.use_restitution(constraints.restitution)
        return True

    def _compiled_free_step(self) -> CompiledFreeStep | None:
        """The free part of the step as one compiled call, where the step allows it.

        With the compiled constraint rows (plane contacts and stops), without midpoint Coriolis
        forces, Coulomb joints or bilateral constraints, and where a C compiler is present.
        Where every joint is a vector space, the same call gives :math:`q^{free}` and solves
        the steps with one active row when the solver's one-row solve is the closed form; on
        a rigid robot with a free-flyer root it gives the velocity terms alone (the
        configuration is advanced by :meth:`_advance`). With friction, for a rigid robot
        without joint friction (W = M) and without one-row steps (frictionless): with the
        tangential rows of the compiled rows, the same call gives :math:`M^{-1} [J^T T^T]`,
        the Delassus matrix of all the rows and the impact law of the normal rows
        (:meth:`_contact_outcome`), rebounds included.
        """
        vector_space, friction = self._vector_space, self._friction
        if (
            self._rows is None
            or (not vector_space and self.flexible is not None)
            or self.midpoint
            or self._coulomb_rows is not None
            or self._bilateral is not None
            or (friction and (self.flexible is not None or self._viscous is not None))
        ):
            return None
        from ucontrol.integrators.compiled_free_step import CompiledFreeStep, ImpactRules

        step = CompiledFreeStep(
            self._data.M,
            self._data.nle,
            self.constraints.size,
            dt=self.dt,
            theta=self.theta,
            horizon=self.gamma * self.dt,
            flexible=self.flexible,
            viscous=self._viscous,
            rules=ImpactRules(
                self.constraints.restitution, self.restitution_threshold, self.newton_law
            ),
            single_rows=vector_space
            and not friction
            and getattr(self.solver, "exact_single", False) is True,
            positions=vector_space,
            tangential=self._rows.tangential,
            several_rows=self._several_rows_compiled(),
        )
        return step if step.compiled else None

    def _several_rows_compiled(self) -> bool:
        """Whether the compiled free step also solves the steps with several active rows.

        Its exact solve on the rows the memory holds is that of the frictionless active-set
        start (:meth:`~ucontrol.solvers.ProxsuiteLCPSolver.solve`, compiled): with that
        solver, frictionless, on a robot whose joints are vector spaces, with at least two
        constraints (of which at most
        :data:`~ucontrol.solvers.compiled_active_set.MAX_ROWS` active).
        """
        solver = self._guessing_solver
        return (
            solver is not None
            and solver.compiled_start
            and self._vector_space
            and not self._friction
            and self.constraints.size >= 2
        )

    @property
    def fast_paths(self) -> tuple[str, ...]:
        """The generated fast paths the steps run, by name.

        ``"constraint rows"`` (gaps, rows and, on small robots, M and h in one compiled call),
        ``"free step"`` (the free velocity, predicted gaps and Delassus terms) and
        ``"single row"`` (a step with one active row), ``"tangent rows"`` (with friction, the
        tangential rows from the compiled rows' call, with the free step's Delassus terms
        where it runs), ``"active-set start"`` (the
        frictionless problem solved on the last step's active set first, the QP only when
        that fails: :meth:`~ucontrol.solvers.ProxsuiteLCPSolver.solve`); none with
        ``compiled = False`` or ``UCONTROL_NO_COMPILE``, the first four none without a C
        compiler.
        """
        free, rows = self._free_step, self._rigid_rows
        paths = (
            ("constraint rows", self._rows is not None),
            ("free step", free is not None),
            ("single row", free is not None and free.single_rows),
            ("several rows", free is not None and free.several_rows),
            ("tangent rows", rows is not None and rows.tangential > 0),
            ("active-set start", self._guessing_solver is not None),
        )
        return tuple(name for name, used in paths if used)

    @property
    def evaluation_data(self) -> pin.Data:
        """The Pinocchio data of the following :meth:`evaluate` calls: ``pin.computeAllTerms``.

        At each call's (q, v) (the links' with flexible joints). For a small rigid robot whose
        compiled rows carry the dynamics (:func:`~ucontrol.contact.compiled_rows.compiled_rows`)
        only M and h are filled (both triangles of M), by the rows' compiled call. A
        controller of the same model may read it between :meth:`evaluate` and :meth:`step`,
        and run further Pinocchio passes on it at that state (e.g. ``computeCoriolisMatrix``)
        as long as they leave M, h and the energies as they are.

        Until it is read, the evaluations of a rigid robot with compiled rows fill only what
        the step reads (:meth:`evaluate`): reading it makes the following ones fill the whole
        data.
        """
        self._shared_data = True
        return self._data

    def evaluate(self, q: Vector, v: Vector, t: float | None = None) -> PlantEvaluation:
        """Dynamics, kinematics and constraint gaps at (q, v) and time t; prepares :meth:`step`.

        Args:
            q: Configuration, shape (nq,) (nq + nf with flexible joints).
            v: Velocity, shape (nv,) (nv + nf with flexible joints).
            t: Time in [s]; required when the constraints have moving surfaces.

        A rigid robot whose constraints are compiled rows
        (:func:`~ucontrol.contact.compiled_rows.compiled_rows`) without the dynamics, whose
        data nobody else reads (:attr:`evaluation_data`), runs only the Pinocchio passes the
        step reads (M by ``crba``, h by ``nonLinearEffects``, the energies from their
        kinematics) instead of ``computeAllTerms`` (which also computes the joints' Jacobians,
        the centre of mass and its Jacobian, the centroidal terms): the same M and energies,
        h to round-off (about 1e-16); Pinocchio's part of a one-contact Panda step falls from
        about 28,000 to 20,000 instructions, of 138,000 (docs/benchmarks.md).

        Raises:
            InvalidParameterError: ``t`` is None and some surface moves.
        """
        rows = self._rigid_rows
        if rows is not None:
            if rows.dynamics or self._shared_data:
                return evaluate_rigid_rows(self._model, self._data, rows, q, v, t)
            model, data = self._model, self._data
            pin.crba(model, data, q, pin.Convention.WORLD)  # the placements of the energy
            pin.nonLinearEffects(model, data, q, v)  # the links' velocities of the energy
            gap, normal_velocity, normal_rows = rows(q, v)
            kinetic = pin.computeKineticEnergy(model, data)
            potential = pin.computePotentialEnergy(model, data)
            return PlantEvaluation(q, v, gap, normal_velocity, kinetic, potential, t, normal_rows)
        return evaluate_plant(
            self._data,
            self.constraints,
            self.flexible,
            q,
            v,
            frames=self._has_contacts,
            t=t,
            rows=self._rows,
        )

    def step(self, state: PlantEvaluation, tau: Vector) -> StepOutcome:
        """Advance one step from ``state`` (the last :meth:`evaluate`) under forces ``tau``.

        The stages of the module docstring: free velocity, active set (with :attr:`memory`),
        impact law, contact problem with the energy guard, position update (and the
        projection onto bilateral constraints); :attr:`memory` then holds what the next step
        needs.

        Args:
            state: The evaluation at the start of the step.
            tau: Generalized forces (actuation plus external), shape (nv,), in [N m] or [N]
                (nv + nf with flexible joints: the motor torques last).
        """
        memory, free_step = self.memory, self._free_step
        inverse_inertia: Callable[[Vector], Vector] | None = None
        q_free: Vector | None = None
        if free_step is not None:  # the stages below in one generated call
            row = free_step.run(state, tau, memory.activation)
            if not memory.first and not self._closure_rules:  # its active set is the step's
                if row >= 0.0 and free_step.single_rows:  # the whole step, from the call
                    return self._single_row_outcome(free_step, int(row), state)
                if row == SEVERAL_ACTIVE_ROWS and free_step.several_rows:
                    outcome = self._several_row_outcome(free_step, state)
                    if outcome is not None:  # (else not solved on the guess: the steps below)
                        return outcome
                if row == NO_ACTIVE_ROW:  # (a free step has no joint or bilateral rows)
                    v_free, q_free, _ = free_step.free_terms()
                    return self._free_outcome(state, v_free, q_free, self._none_active)
            v_free, q_free, predicted = free_step.free_terms()
        else:
            v_free, inverse_inertia = self._free_velocity(state, tau)
            # Predicted gaps [m] or [rad]; held constraints stay in while barely open.
            predicted = predicted_gaps(state.gap, state.normal_velocity, self.gamma * self.dt)
        if self._closure_rules:  # contacts that may not close here (a scuffing swing foot)
            predicted = self._barred(state, predicted, memory)
        active, activation = active_set(memory, state.gap, predicted, self._release)
        indices = active.nonzero()[0]
        count = indices.size
        if not count and not self._problem_rows:  # no contact problem: nothing held next
            return self._free_outcome(state, v_free, q_free, active)
        # One active row, the whole problem (a free step has no joint or bilateral rows).
        if count == 1 and free_step is not None and free_step.single_rows and not memory.first:
            return self._single_row_outcome(free_step, indices.item(0), state)
        return self._contact_outcome(state, v_free, inverse_inertia, active, indices, activation)

    def _free_outcome(
        self,
        state: PlantEvaluation,
        v_free: Vector,
        q_free: Vector | None,
        active: NDArray[np.bool_],
    ) -> StepOutcome:
        """The outcome of a step without a contact problem: nothing held next.

        ``q_free`` is the compiled call's :math:`q^{free}`, or None (advanced here).
        """
        self.memory = self._free_memory
        q_next = self._advance_theta(state, v_free) if q_free is None else q_free
        return StepOutcome(
            q_next,
            v_free,
            self._no_impulse,
            active,
            None,
            friction_impulse=self._no_friction_impulse,
        )

    def _barred(self, state: PlantEvaluation, predicted: Vector, memory: StepMemory) -> Vector:
        """``predicted`` with the contacts barred from closing at q_k (not held) left out.

        :meth:`~ucontrol.contact.ConstraintSet.closure_barred`: their predicted gaps become
        infinite, so that the active set leaves them out.
        """
        q = state.q if self.flexible is None else state.q[: self.flexible.nq]
        barred = [i for i in self.constraints.closure_barred(q) if memory.activation[i] <= 0.0]
        if not barred:
            return predicted
        predicted = predicted.copy()
        predicted[barred] = np.inf
        return predicted

    def _single_row_outcome(
        self, free_step: CompiledFreeStep, i: int, state: PlantEvaluation
    ) -> StepOutcome:
        """The outcome of a step from ``state`` with constraint ``i`` alone active.

        From the compiled call, whose one-row step also says whether it is an impact
        (:func:`~ucontrol.integrators.step_stages.is_impact`, at the step's start t_k, 0 when
        ``state`` has no time). The one-row LCP's closed form is part of the compiled step:
        its solve time is not measured apart (0 s in the solution).
        """
        step = free_step.single_row(i)
        impulse, P, velocity, P_i, residual, solved, plastic, impact, v_next, q_next = step
        status = "solved" if solved else "infeasible"
        solution = ContactSolution(P, velocity, status, 0, residual, 0.0)
        if not solved:
            self._checked(self.solver, solution)
        impacts = ((i, 0.0 if state.t is None else float(state.t)),) if impact else ()
        # next_memory(impulse, (i,), ...), built once
        self.memory = self._row_memories[i] if P_i > 0.0 else self._free_memory
        active = self._row_actives[i]
        return StepOutcome(q_next, v_next, impulse, active, solution, 0, plastic, None, impacts)

    def _several_row_outcome(
        self, free_step: CompiledFreeStep, state: PlantEvaluation
    ) -> StepOutcome | None:
        """The outcome of a step with several active rows from the compiled call, or None.

        None where the call's exact solve on the held rows does not solve the step's LCP
        (:meth:`~ucontrol.integrators.compiled_free_step.CompiledFreeStep.several_row`):
        :meth:`_contact_outcome` then solves it. The solution is the active-set start's
        (polished, no QP iteration); its solve time, part of the call, is not measured apart
        (0 s).
        """
        step = free_step.several_row()
        if step is None:
            return None
        impulse, velocity, residual, active_mask, held, impact_mask, v_next, q_next = step
        masks = self._masks
        active, rows, _ = masks.get(active_mask) or self._mask_terms(active_mask)
        solution = ContactSolution(impulse[rows], velocity[rows], "solved", 0, residual, 0.0, True)
        self.memory = (masks.get(held) or self._mask_terms(held))[2]
        impacts: tuple[tuple[int, float], ...] = ()
        if impact_mask:
            t_k = 0.0 if state.t is None else float(state.t)
            closing = (masks.get(impact_mask) or self._mask_terms(impact_mask))[1]
            impacts = tuple((i, t_k) for i in closing.tolist())
        return StepOutcome(q_next, v_next, impulse, active, solution, 0, False, None, impacts)

    def _mask_terms(self, mask: int) -> tuple[NDArray[np.bool_], NDArray[np.intp], StepMemory]:
        """The rows of ``mask`` (bit i for constraint i): a set (n,), indices, a memory.

        The memory is that after a step whose impulses are on those rows; each read-only,
        remembered and shared by the following steps.
        """
        rows = np.array([mask >> i & 1 for i in range(self.constraints.size)], dtype=bool)
        indices = rows.nonzero()[0]
        held = next_memory(rows.astype(float), indices, self._release).activation
        terms = _read_only(rows), _read_only(indices), StepMemory(_read_only(held), False)
        self._masks[mask] = terms
        return terms

    def _contact_outcome(
        self,
        state: PlantEvaluation,
        v_free: Vector,
        inverse_inertia: Callable[[Vector], Vector] | None,
        active: NDArray[np.bool_],
        indices: NDArray[np.intp],
        activation: Vector,
    ) -> StepOutcome:
        r"""Impact law, contact problem, energy guard and position update of a step.

        The rows of the contact problem are the active constraints' normal rows, their
        tangential rows (with friction), the Coulomb joints' rows and the bilateral rows, in
        this order; Newton's law and the closures act on the normal rows, the energy guard
        measures every row but the bilateral ones (module docstring).
        """
        constraints, data, m = self.constraints, self._data, indices.size
        rows = indices.tolist()  # (Python ints: the loops over the active rows below)
        free_step = self._free_step if inverse_inertia is None else None  # its terms computed
        tangents: NDArray[np.intp] | None = None
        terms_rows = indices  # the rows of the free step's Delassus terms
        friction_map: Vector | None = None  # the compiled rows' friction impulses, if read
        counts = constraints.tangent_count[indices]
        compiled = self._rigid_rows
        if self._friction and np.count_nonzero(counts):  # normal and tangential rows together
            tangents = counts
            if (
                compiled is not None
                and compiled.tangential
                and state.normal_rows is compiled.last_rows
                and compiled.last_contact_rows is not None
            ):  # the state's compiled call holds them (and the free step their terms)
                terms_rows, friction_map = compiled.contact_selection(indices)
                J = compiled.last_contact_rows[terms_rows]
            else:
                if compiled is not None:  # the frame Jacobians, which the rows do not read
                    pin.computeJointJacobians(self._model, data, state.q)
                J, T, directions = constraints.contact_rows(data, indices)
                J = np.concatenate((J, T))
                if inverse_inertia is None:  # W = M (_compiled_free_step): M⁻¹ [Jᵀ Tᵀ]
                    pin.cholesky.decompose(self._model, data)
                    inverse_inertia = self._rigid_inverse_inertia
        elif state.normal_rows is not None:  # (every row active: the rows as they are)
            J = state.normal_rows if m == constraints.size else state.normal_rows[indices]
        else:
            J = constraints.jacobian(data, indices)
        if self.flexible is not None:  # constraints act on the links only
            J = np.hstack((J, np.zeros((J.shape[0], self.flexible.nf))))
        if self._coulomb_rows is not None:  # Coulomb joints' rows after the contacts'
            J = np.vstack((J, self._coulomb_rows))
        m_b, bilateral_offset = 0, None
        if self._bilateral is not None:  # bilateral rows last, their impulses free
            J_b, bilateral_offset = self._bilateral_rows(state)
            if self.flexible is not None:
                J_b = np.hstack((J_b, np.zeros((J_b.shape[0], self.flexible.nf))))
            J, m_b = np.vstack((J, J_b)), J_b.shape[0]
        if inverse_inertia is None:  # the compiled free step's terms
            assert free_step is not None
            Minv_Jt, D = free_step.contact_terms(terms_rows)
        else:
            Minv_Jt = inverse_inertia(J)
            D = J.dot(Minv_Jt)
        u_free = J.dot(v_free)
        r = u_free.size - m_b  # the rows the energy guard measures
        rate_now: Vector | float = 0.0
        if constraints.time_dependent and m:  # velocities relative to moving surfaces
            rate_now, rate_next = self._surface_rates(indices, tangents, state.t)
            rate_now = _pad(rate_now, r)
            u_free[:r] += _pad(rate_next, r)
        held_rows: NDArray[np.bool_] | None = None
        if free_step is not None and activation is self.memory.activation:
            # by the free step, same activation (0 on the tangential rows)
            rebound, closure = free_step.offsets(terms_rows)
        else:  # the impact law on the normal rows
            held_rows = activation[indices] > 0.0
            rebound, closure = newton_offsets(
                NUMPY_OPS,
                state.gap[indices],
                state.normal_velocity[indices],
                constraints.restitution[indices],
                held_rows,
                self.dt,
                self.restitution_threshold,
                self.newton_law == "siconos",
                self._plastic,
            )
        if u_free.size > rebound.size:  # no offsets on the other rows but bilateral closures
            rebound, closure = _pad(rebound, u_free.size), _pad(closure, u_free.size)
            if m_b and bilateral_offset is not None:  # (module docstring)
                closure[-m_b:] = bilateral_offset
        b = u_free + closure
        guess = None
        if self._guessing_solver is not None and tangents is None:  # the last step's active rows
            if held_rows is None:  # (every row active: the activation as it is)
                thresholds = activation if m == constraints.size else activation[indices]
                held_rows = thresholds > 0.0
            guess = held_rows
        solution = self._solve(D, b + rebound, indices, tangents, m_b, guess)
        plastic = False
        if self._guarded and np.count_nonzero(rebound):  # the energy guard
            u_plus = solution.velocity[:r] - rebound[:r] - closure[:r]
            u_k = J[:r].dot(state.v) + rate_now
            gain = impulse_energy_gain(
                NUMPY_OPS, solution.impulses[:r], u_free[:r], u_plus, u_k, self.theta
            )
            if gains_energy(gain, state.kinetic_energy):
                solution, plastic = self._solve(D, b, indices, tangents, m_b, guess), True
        impulse = np.zeros(constraints.size)
        impulse[indices] = solution.impulses[:m]
        friction_impulse: Vector | None = None
        if friction_map is not None:  # the active set's map (constant tangents), (n, 3)
            contact_impulses = solution.impulses[: friction_map.shape[1]]
            friction_impulse = friction_map.dot(contact_impulses).reshape(-1, 3)
        elif self._friction:
            friction_impulse = np.zeros((constraints.size, 3))
            if tangents is not None:
                _add_friction_impulses(friction_impulse, indices, tangents, directions, solution)
        v_next = v_free + Minv_Jt.dot(solution.impulses)
        q_next = self._advance_theta(state, v_next)
        if constraints.clearances:  # journals back into their bearings (clearance_joint)
            q_next = constraints.clamp_play(q_next)
        if self._bilateral is not None:  # held contacts' normal rows kept by the projection
            held = np.vstack(
                (J[:m][impulse[indices] > 0.0, : self.robot.nv], constraints.play_rows(q_next))
            )
            q_next = self._project(q_next, held if held.size else None)
        impacts = _closing_impacts(impulse, self.memory.activation, rows, state)
        self.memory = next_memory(impulse, rows, self._release)
        return StepOutcome(
            q_next, v_next, impulse, active, solution, 0, plastic, friction_impulse, impacts
        )

    def _advance_theta(self, state: PlantEvaluation, v_next: Vector) -> Vector:
        r""":math:`q_k \oplus \mathrm{h}\big((1 - \theta) v_k + \theta v_{k+1}\big)` (step 4)."""
        return self._advance(state.q, theta_displacement(state.v, v_next, self.dt, self.theta))

    def _project(self, q: Vector, held: Vector | None = None) -> Vector:
        r"""``q`` moved onto h(q) = 0 by Gauss–Newton steps of least norm (links only).

        Args:
            q: Configuration after the step, shape (nq,) (nq + nf with flexible joints).
            held: Normal rows :math:`J_n(q_k)` of the contacts that carried an impulse in the
                step, shape (k, nv), or None: the steps then also satisfy
                :math:`J_n \delta q = 0`, so that the projection does not push a held contact
                into its surface (its gap is kept to first order).
        """
        assert self._bilateral is not None
        model, data, bilateral = self._model, self._projection_data, self._bilateral
        nq = self.robot.nq
        q1 = q[:nq]
        for _ in range(BILATERAL_PROJECTION_ITERATIONS):
            pin.framesForwardKinematics(model, data, q1)
            residual = bilateral.residual(data, q1)
            if np.max(np.abs(residual)) <= BILATERAL_PROJECTION_TOLERANCE:
                break
            pin.computeJointJacobians(model, data, q1)
            if held is None:
                step = np.linalg.lstsq(bilateral.jacobian(data), residual, rcond=None)[0]
            else:
                rows = np.vstack((bilateral.jacobian(data), held))
                target = np.concatenate((residual, np.zeros(held.shape[0])))
                step = np.linalg.lstsq(rows, target, rcond=None)[0]
            q1 = pin.integrate(model, q1, -step)
        return q1 if q.size == nq else np.concatenate((q1, q[nq:]))

    def _checked(self, solver: Any, solution: ContactSolution) -> ContactSolution:
        """``solution``, or :class:`ContactSolveError` / a warning when it is unsolved."""
        if solution.status != "solved":
            if self.on_unsolved == "raise":
                raise ContactSolveError(
                    solver.name, solution.status, solution.residual, solver.residual_tolerance
                )
            warnings.warn(
                ContactSolveWarning(
                    solver.name, solution.status, solution.residual, solver.residual_tolerance
                ),
                stacklevel=4,
            )
        return solution

    def _surface_rates(
        self, indices: NDArray[np.intp], tangents: NDArray[np.intp] | None, t: float | None
    ) -> tuple[Vector, Vector]:
        r""":math:`\partial u / \partial t` terms of the rows at :math:`t_k` and :math:`t_{k+1}`.

        Normal rows first, then the tangential ones, in [m/s].
        """
        if t is None:
            raise InvalidParameterError(
                "state.t",
                t,
                "the time of the evaluation in [s] (evaluate(q, v, t)): the "
                "constraints have moving surfaces",
            )
        rates = []
        for time in (t, t + self.dt):
            rate = self.constraints.normal_rate(indices, time)
            if tangents is not None:
                rate = np.concatenate((rate, self.constraints.tangent_rate(indices, time)))
            rates.append(rate)
        return rates[0], rates[1]

    def _rigid_inverse_inertia(self, J: Vector) -> Vector:
        """:math:`M^{-1} J^T` for rows J (m, nv), with M factorized in the data buffer.

        By the root's subtrees where M is block diagonal over several
        (:class:`~ucontrol.model.root_subtrees.RootSubtrees`, found on the first product).
        """
        model, data = self._model, self._data
        if J.shape[0] == 1:  # one triangular solve instead of M⁻¹
            return pin.cholesky.solve(model, data, J[0])[:, None]
        Minv = pin.cholesky.computeMinv(model, data)
        return self._root_subtrees.inverse_inertia_rows(Minv, J)

    @functools.cached_property
    def _root_subtrees(self) -> RootSubtrees:
        """The root's subtrees of the robot (dense products where M is not blocked by them)."""
        from ucontrol.model.root_subtrees import RootSubtrees

        return RootSubtrees(self._model)

    def _free_velocity(
        self, state: PlantEvaluation, tau: Vector
    ) -> tuple[Vector, Callable[[Vector], Vector]]:
        r"""Free velocity of the step (stage 1), and the map J ↦ W⁻¹ Jᵀ.

        W is the inertia (of the links at q_k or at the midpoint, and of the motors) plus the
        θ-implicit spring, damper and joint viscous friction terms; with ``midpoint`` the
        Coriolis forces are the symmetric :math:`\Gamma(v_k, v^*)` of a first solve's velocity
        :math:`v^*`. Where W is M(q_k) alone it is factored by Pinocchio's Cholesky (which
        follows the kinematic tree's sparsity), else by LAPACK's.
        """
        model, h, flexible = self._model, self.dt, self.flexible
        if flexible is None and not self.midpoint and self._viscous is None:  # W = M(q_k)
            data = self._data
            pin.cholesky.decompose(model, data)
            v_free = state.v + h * pin.cholesky.solve(model, data, tau - data.nle)
            return v_free, self._rigid_inverse_inertia
        nv = self.robot.nv
        q1, v1 = (state.q, state.v) if flexible is None else flexible.split(state.q, state.v)[:2]
        force = tau.copy()
        if self.midpoint:
            data = self._midpoint_data
            assert data is not None
            q_mid = self._midpoint_configuration(q1, v1)
            pin.crba(model, data, q_mid)
            force[:nv] -= pin.computeGeneralizedGravity(model, data, q_mid)
        else:
            data, q_mid = self._data, q1
            force[:nv] -= data.nle
        M = data.M  # upper triangle (crba): the only one the Cholesky factorization reads
        if flexible is None:
            W = M.copy()
        else:
            force += flexible.transmission_forces(state.q, state.v)
            force -= (h * self.theta) * (self._stiffness @ state.v)
            W = self._implicit_forces.copy()
            W[:nv, :nv] += M
        if self._viscous is not None:  # θ-implicit joint viscous friction (module docstring)
            force[:nv] -= self._viscous * v1  # -D v_k [N m]
            links = np.arange(nv)
            W[links, links] += (h * self.theta) * self._viscous  # + hθD
        factor = _upper_cholesky(W)
        if self.midpoint:
            first = force.copy()  # Coriolis at v_k: a predictor
            first[:nv] -= self._coriolis(data, q_mid, v1, v1)
            v_star = state.v + _cholesky_solve(factor, h * first)
            if self._bilateral is not None:  # the predictor held by the closures
                v_star += self._bilateral_correction(state, factor, v_star)
            force[:nv] -= self._coriolis(data, q_mid, v1, v_star[:nv])
        v_free = state.v + _cholesky_solve(factor, h * force)
        return v_free, lambda J: _cholesky_solve(factor, J.T)

    def _midpoint_configuration(self, q1: Vector, v1: Vector) -> Vector:
        r""":math:`q_{k+1/2} = q_k \oplus \tfrac h2 v_k` of the links, shape (nq,)."""
        return pin.integrate(self._model, q1, (0.5 * self.dt) * v1)

    def _bilateral_rows(self, state: PlantEvaluation) -> tuple[Vector, Vector | None]:
        r"""Rows :math:`J_b` of the bilateral constraints in step 3, and their offsets.

        Without ``midpoint``: :math:`J_b(q_k)`, shape (m_b, nv), and None
        (:math:`J_b v_{k+1} = 0`). With it (module docstring): :math:`J_b(q_{k+1/2})` and the
        offsets :math:`(J_b(q_{k+1/2}) - J_b(q_k))\, v_k` in [m/s] or [rad/s], shape (m_b,),
        so that the step's condition :math:`J_b(q_{k+1/2}) v_{k+1} + \text{offsets} = 0` is
        :math:`J_b(q_{k+1}) v_{k+1} = 0` to :math:`O(h^2)`. The midpoint's kinematics run on
        the projection's buffer (free until :meth:`_project`).
        """
        assert self._bilateral is not None
        J_k = self._bilateral.jacobian(self._data)
        if not self.midpoint:
            return J_k, None
        model, data, flexible = self._model, self._projection_data, self.flexible
        q1, v1 = (state.q, state.v) if flexible is None else flexible.split(state.q, state.v)[:2]
        pin.computeJointJacobians(model, data, self._midpoint_configuration(q1, v1))
        pin.updateFramePlacements(model, data)
        J_mid = self._bilateral.jacobian(data)
        return J_mid, (J_mid - J_k).dot(v1)

    def _bilateral_correction(
        self, state: PlantEvaluation, factor: Vector, v_star: Vector
    ) -> Vector:
        r"""Velocity change :math:`W^{-1} J_b^T P` that makes ``v_star`` meet step 3's closures.

        The midpoint predictor :math:`v^*` of the Coriolis forces must be within
        :math:`O(h^2)` of :math:`v_{k+1}`; a free one misses the closures' impulses, O(h), and
        the step would be of order one (module docstring). P solves the bilateral rows of
        :meth:`_bilateral_rows` alone, in least squares (dependent rows), shape (nv,) (nv + nf
        with flexible joints).
        """
        J, offsets = self._bilateral_rows(state)
        assert offsets is not None  # the midpoint's rows
        if self.flexible is not None:  # constraints act on the links only
            J = np.hstack((J, np.zeros((J.shape[0], self.flexible.nf))))
        Winv_Jt = _cholesky_solve(factor, J.T)
        rhs = -(J.dot(v_star) + offsets)
        return Winv_Jt.dot(np.linalg.lstsq(J.dot(Winv_Jt), rhs, rcond=None)[0])

    def _coriolis(self, data: pin.Data, q: Vector, a: Vector, b: Vector) -> Vector:
        r"""Symmetric Coriolis and centrifugal forces :math:`\Gamma(q; a, b)`, shape (nv,).

        :math:`\Gamma(q; v, v) = C(q, v) v`, polarized from Pinocchio's RNEA at zero
        acceleration (gravity cancels in the difference).
        """
        model, zero = self._model, self._zero_acceleration
        plus = pin.rnea(model, data, q, a + b, zero).copy()
        return 0.25 * (plus - pin.rnea(model, data, q, a - b, zero))

    def _advance(self, q: Vector, dq: Vector) -> Vector:
        r"""``q ⊕ dq``: Pinocchio's integration on the links, a sum on the motors.

        Free-flyer and planar joints move their origin along a straight line, by their linear
        velocity rotated to the world at step k, and rotate by the exponential of their angular
        velocity (:math:`\mathbb{R}^3 \times SO(3)`, module docstring).
        """
        if self._vector_space:
            return q + dq
        if self.flexible is None:
            q_next = pin.integrate(self._model, q, dq)
        else:
            nq, nv = self.flexible.nq, self.flexible.nv
            q_next = np.concatenate((pin.integrate(self._model, q[:nq], dq[:nv]), q[nq:] + dq[nv:]))
        for iq, iv in self._free_flyers:
            rotation = pin.XYZQUATToSE3(q[iq : iq + 7]).rotation
            q_next[iq : iq + 3] = q[iq : iq + 3] + rotation @ dq[iv : iv + 3]
        for iq, iv in self._planar_joints:
            c, s = q[iq + 2], q[iq + 3]
            q_next[iq : iq + 2] = q[iq : iq + 2] + np.array(
                (c * dq[iv] - s * dq[iv + 1], s * dq[iv] + c * dq[iv + 1])
            )
        return q_next

    def _solve(
        self,
        D: Vector,
        b: Vector,
        indices: NDArray[np.intp],
        tangents: NDArray[np.intp] | None,
        equalities: int = 0,
        guess: NDArray[np.bool_] | None = None,
    ) -> ContactSolution:
        """The contact problem (D, b) of the constraints ``indices``.

        Frictionless when ``tangents`` is None and no joint has Coulomb friction (a mixed
        problem with ``equalities`` bilateral rows last; without them and with the
        ``"active-set start"`` path, solved first on the active set ``guess`` of the last
        step, shape (m,)), else a Coulomb problem whose
        constraint ``indices[j]`` has ``tangents[j]`` tangential rows, followed by the
        Coulomb joints' rows and the ``equalities`` bilateral rows. An unsolved problem raises
        :class:`ContactSolveError` or warns, as ``on_unsolved`` says.
        """
        solver: LCPSolver | CoulombSolver
        if self._coulomb_rows is not None:
            assert self.friction_solver is not None
            solution = self._solve_with_joints(D, b, indices, tangents, equalities)
            return self._checked(self.friction_solver, solution)
        if tangents is None or self.friction_solver is None:  # the latter: not with tangents
            solver = self.solver
            if equalities:  # bilateral rows last (checked at construction: proxsuite's)
                solution = self.solver.solve_mixed(D, b, equalities)  # type: ignore[attr-defined]
            elif guess is not None and self._guessing_solver is not None:
                solution = self._guessing_solver.solve(D, b, guess)
            else:
                solution = self.solver.solve(D, b)
        else:
            solver = self.friction_solver
            problem = CoulombProblem(D, b, self.constraints.friction[indices], tangents, equalities)
            solution = self.friction_solver.solve_coulomb(problem)
        return self._checked(solver, solution)

    def _solve_with_joints(
        self,
        D: Vector,
        b: Vector,
        indices: NDArray[np.intp],
        tangents: NDArray[np.intp] | None,
        equalities: int = 0,
    ) -> ContactSolution:
        r"""The contact problem with the Coulomb joints' rows last (module docstring).

        Each Coulomb joint j becomes a planar contact of the Coulomb problem with
        :math:`\mu = 1`: its tangential row is the joint's (:math:`u = v_j^+`) and its normal
        row an auxiliary one, decoupled from every other, :math:`u_n = \sigma_j (P_n - h F_{c,j})`
        (:math:`\sigma_j = D_{jj}`), so that :math:`P_n = h F_{c,j}` at every solution. The
        returned solution has the rows of (D, b): the auxiliary ones are dropped. The
        ``equalities`` bilateral rows, after the joints' ones, stay last.
        """
        assert self.friction_solver is not None
        m, m_j = indices.size, self._coulomb_bounds.size
        r = D.shape[0]  # m normal, the contacts' tangential, m_j joint, then bilateral rows
        real = np.concatenate((np.arange(m), np.arange(m + m_j, r + m_j)))
        auxiliary = np.arange(m, m + m_j)
        joint_rows = np.arange(r - equalities - m_j, r - equalities)
        D_all = np.zeros((r + m_j, r + m_j))
        D_all[np.ix_(real, real)] = D
        sigma = D.diagonal()[joint_rows].copy()
        D_all[auxiliary, auxiliary] = sigma
        b_all = np.zeros(r + m_j)
        b_all[real] = b
        b_all[auxiliary] = -sigma * self._coulomb_bounds  # [rad/s]
        contact_tangents = np.zeros(m, dtype=np.intp) if tangents is None else tangents
        mu = self.constraints.friction[indices] if tangents is not None else np.zeros(m)
        problem = CoulombProblem(
            D_all,
            b_all,
            np.concatenate((mu, np.ones(m_j))),
            np.concatenate((contact_tangents, np.ones(m_j, dtype=np.intp))),
            equalities,
        )
        solution = self.friction_solver.solve_coulomb(problem)
        return solution._replace(impulses=solution.impulses[real], velocity=solution.velocity[real])


@functools.cache
def _lapack_cholesky() -> tuple[Any, Any]:
    """LAPACK's ``dpotrf`` and ``dpotrs``, loaded by the first step needing them."""
    from ucontrol.solvers.lapack_routines import lapack_routine

    return lapack_routine("dpotrf"), lapack_routine("dpotrs")


def _upper_cholesky(W: Vector) -> Vector:
    """Upper Cholesky factor of the symmetric positive definite W (its upper triangle read).

    LAPACK's ``potrf``, as ``scipy.linalg.cho_factor`` calls it, without that wrapper's
    checks (which cost more than the factorization of a small W: docs/benchmarks.md).

    Raises:
        numpy.linalg.LinAlgError: W is not positive definite.
    """
    factor, info = _lapack_cholesky()[0](W, lower=False, clean=False)
    if info != 0:
        raise np.linalg.LinAlgError(f"the iteration matrix W is not positive definite ({info})")
    return factor


def _cholesky_solve(factor: Vector, b: Vector) -> Vector:
    """``W⁻¹ b`` from :func:`_upper_cholesky`'s factor; b of shape (n,) or (n, k)."""
    x, _ = _lapack_cholesky()[1](factor, b, lower=False)
    return x


def _add_friction_impulses(
    friction_impulse: Vector,
    indices: NDArray[np.intp],
    tangents: NDArray[np.intp],
    directions: Vector,
    solution: ContactSolution,
) -> None:
    """Add the tangential impulses of ``solution`` to their constraints' rows, in [N s].

    Args:
        friction_impulse: World friction impulse of every constraint, shape (n, 3), updated.
        indices: Active constraints, shape (m,); their normal rows come first in ``solution``.
        tangents: Tangential rows of each active constraint (0, 1 or 2), shape (m,).
        directions: World direction of each tangential row, shape (sum(tangents), 3).
        solution: The step's contact solution (normal rows, then the tangential ones).
    """
    rows = solution.impulses[indices.size : indices.size + directions.shape[0], None]
    count = int(tangents[0])
    if count and rows.shape[0] == count * indices.size:  # the same count on every constraint
        # Each constraint's impulse along its tangents, summed over them in order.
        per_constraint = (rows * directions).reshape(indices.size, count, 3)
        friction_impulse[indices] = per_constraint.sum(axis=1)
        return
    frictional = tangents > 0
    first_rows = np.cumsum(tangents[frictional]) - tangents[frictional]  # of each owner
    friction_impulse[indices[frictional]] = np.add.reduceat(rows * directions, first_rows)


_Array = TypeVar("_Array", bound=np.ndarray)


def _read_only(array: _Array) -> _Array:
    """``array``, made read-only (an outcome shared between steps)."""
    array.flags.writeable = False
    return array


def _closing_impacts(
    impulse: Vector, activation: Vector, rows: Any, state: PlantEvaluation
) -> tuple[tuple[int, float], ...]:
    """(constraint, t_k in [s]) of the impacts among ``rows`` in the step from ``state``.

    :func:`~ucontrol.integrators.step_stages.is_impact` with the last step's ``activation``
    (t_k = ``state.t``, 0 when None): time-stepping locates no impact, so its time is the
    step's start.
    """
    u_minus, t_k = state.normal_velocity, 0.0 if state.t is None else float(state.t)
    # Python floats (a third of numpy scalars' cost)
    impulse, activation, u_minus = impulse.tolist(), activation.tolist(), u_minus.tolist()
    impacts: tuple[tuple[int, float], ...] = ()
    for i in rows:
        if is_impact(impulse[i], activation[i], u_minus[i]):
            impacts += ((int(i), t_k),)
    return impacts


def _pad(rows: Vector, size: int) -> Vector:
    """``rows`` (normal rows) followed by zeros (tangential rows), shape (size,)."""
    if rows.size == size:
        return rows
    padded = np.zeros(size)
    padded[: rows.size] = rows
    return padded


def _default_friction_solver() -> CoulombSolver:
    """A :class:`~ucontrol.solvers.ProxsuiteCoulombSolver`, imported only when needed."""
    from ucontrol.solvers.proxsuite_coulomb import ProxsuiteCoulombSolver

    return ProxsuiteCoulombSolver()
