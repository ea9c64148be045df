r"""A cycle's nonlinear program solved with its derivatives compiled to C, cached across runs.

IPOPT spends a design's time in the derivatives casadi builds from the program: the
Lagrangian's Hessian (forward over reverse through every Runge–Kutta stage) and the
constraints' Jacobian, run in casadi's virtual machine. Here the functions IPOPT calls
(``nlp_f``, ``nlp_g``, ``nlp_grad_f``, ``nlp_jac_g``, ``nlp_hess_l``, ``nlp_grad``) are
generated as C once (``casadi.CodeGenerator``), compiled into the cache of
:mod:`ucontrol.model.compile_cache` and loaded back as the solver
(``casadi.nlpsol(name, "ipopt", library)``): a later run of the same program builds no
derivative at all. The intervals are calls of one substep Function
(``_rk_interval(..., called=True)`` in :mod:`.cycle_transcription`), so that the C holds
each derivative of a substep once.

- Key: the program's definition, its serialized form (``Function.serialize`` of
  :math:`(x, p) \mapsto (f, g)`: every constant and interval; the bounds are arguments of the
  solve), with this module's source, IPOPT's Hessian approximation (which functions there
  are) and the installed casadi (:func:`~ucontrol.model.compile_cache.definition_key`): a
  changed task builds another library, an unchanged one is loaded.
- Same program: the operations of the virtual machine's inlined intervals, grouped by
  substep, whose rounding alone differs (two-link: the same 22 iterations, the cost 1.1e-15
  apart relative; docs/benchmarks.md, "Issue 30, item 4: fifth round").
- Large programs (``background``: the Panda's MX intervals, 31 MB of C, 4 to 11 minutes of
  ``gcc -O1`` and 2.2 GB): the first run does not wait for the compiler. It writes the C,
  starts its build in a detached, niced process (``build_library(..., background=True)``),
  says so on the terminal and solves in the virtual machine; a run while the build goes on
  solves there too without starting another; a later run loads the library. A failed build
  leaves no library and no lock but its marker: later runs do not start it again until the
  marker is removed (:func:`~ucontrol.model.compile_cache.failure_marker`).
- Fallback: :func:`solve_compiled` returns None without a C compiler or when the build fails;
  the caller then solves in casadi's virtual machine, as it does where
  ``UCONTROL_NO_COMPILE=1`` (:class:`~ucontrol.design.cycle_transcription.CycleTranscription`
  asks for no compiled solve then).
"""

from __future__ import annotations

import hashlib
import logging
import subprocess
from collections.abc import Callable, Sequence
from typing import Any

import casadi as ca

from ucontrol.model.compile_cache import build_library, definition_key

#: Start of the library's file name (and the C code's name).
STEM = "design_nlp"
#: Said once on the terminal before the first build of a program.
NOTICE = (
    "this design's derivatives (first run of a task only: about a minute; later runs load them)"
)
#: Said on the terminal when a large program's build starts in the background.
BACKGROUND_NOTICE = (
    "this design's derivatives (a large program: 4 to 11 minutes, niced; this run solves "
    "without them, later runs of this task load them)"
)

_logger = logging.getLogger(__name__)


def solve_compiled(
    opti: ca.Opti,
    options: dict[str, Any],
    ipopt: dict[str, Any],
    on_iteration: Callable[[int, Callable[[], dict[str, Any]]], None] | None = None,
    *,
    background: bool = False,
) -> tuple[Callable[[Any], Any], dict[str, Any]] | None:
    """Solve ``opti``'s program with IPOPT on its compiled derivatives.

    Args:
        opti: The program, its initial values set.
        options: The nlpsol options (``print_time``, ``error_on_fail``).
        ipopt: IPOPT's options.
        on_iteration: Called after each IPOPT iteration with its number (from 0) and a
            function returning the solver's statistics so far (``iterations``: ``obj``,
            ``inf_pr``, ``inf_du``).
        background: Where the library is not built yet, build it in a detached background
            process and return None (a large program, whose compiler would take minutes).

    Returns:
        A function evaluating an expression of ``opti``'s variables and constraint
        multipliers at the solution, and the solver's statistics; or None where nothing
        compiled can be used yet (no C compiler, a failed build, a background build started
        or running: the caller solves in casadi's virtual machine).
    """
    x, p = opti.x, opti.p
    program = ca.Function("nlp", [x, p], [opti.f, opti.g], ["x", "p"], ["f", "g"])
    nlp = {"x": x, "p": p, "f": opti.f, "g": opti.g}
    settings = {**options, "ipopt": ipopt}

    def source() -> str:
        built = ca.nlpsol(STEM, "ipopt", nlp, settings)
        code = ca.CodeGenerator(STEM)
        code.add(program)
        for name in built.get_function():
            code.add(built.get_function(name))
        return str(code.dump())

    try:
        # the Hessian's approximation decides which functions there are (no nlp_hess_l with
        # limited-memory); IPOPT's other options are read at the solve, not compiled
        hessian = ipopt.get("hessian_approximation", "exact")
        key = definition_key([_definition(opti), hessian], [__name__])
        notice = BACKGROUND_NOTICE if background else NOTICE
        library = build_library(STEM, key, source, notice=notice, background=background)
        if library is None:
            _logger.info("design derivatives built in the background: casadi's virtual machine")
            return None
        if on_iteration is not None:
            sizes = {"x": x.numel(), "g": opti.g.numel(), "p": p.numel()}
            callback = _IterationCallback(sizes, on_iteration, lambda: solver.stats())
            settings = {**settings, "iteration_callback": callback}
        solver = ca.nlpsol(STEM, "ipopt", str(library), settings)
    except (OSError, RuntimeError, subprocess.SubprocessError) as error:
        _logger.info("design derivatives not compiled (%s): casadi's virtual machine", error)
        return None
    result = solver(
        x0=opti.debug.value(x, opti.initial()),
        p=opti.debug.value(p),
        lbg=opti.debug.value(opti.lbg),
        ubg=opti.debug.value(opti.ubg),
    )
    solution, multipliers = result["x"], result["lam_g"]

    def value(expr: Any) -> Any:
        return ca.Function("value", [x, opti.lam_g], [expr])(solution, multipliers)

    return value, dict(solver.stats())


def _definition(opti: ca.Opti) -> str:
    r"""SHA-256 of the program :math:`(x, p) \mapsto (f, g)` serialized, its symbols renamed.

    An Opti's variables are named after the Opti's instance number in the process: renamed by
    position, the same program has the same definition in every process and every instance.
    """
    named = ca.symvar(ca.vertcat(opti.x, opti.p))
    renamed = [ca.MX.sym(f"v{i}", symbol.sparsity()) for i, symbol in enumerate(named)]
    program = ca.Function("nlp", renamed, ca.substitute([opti.f, opti.g], named, renamed))
    return hashlib.sha256(program.serialize().encode()).hexdigest()


class _IterationCallback(ca.Callback):  # type: ignore[misc]
    """IPOPT's ``iteration_callback``: passes each iteration's number on, never stops it."""

    def __init__(
        self,
        sizes: dict[str, int],
        on_iteration: Callable[[int, Callable[[], dict[str, Any]]], None],
        stats: Callable[[], dict[str, Any]],
    ) -> None:
        ca.Callback.__init__(self)
        self._sizes = {
            name: sizes[name[4:] if name.startswith("lam_") else name]
            for name in (ca.nlpsol_out(i) for i in range(ca.nlpsol_n_out()))
            if name != "f"
        }
        self._on_iteration, self._stats, self._count = on_iteration, stats, 0
        self.construct("iterations", {})

    def get_n_in(self) -> int:
        return int(ca.nlpsol_n_out())

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return str(ca.nlpsol_out(i))

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self._sizes.get(ca.nlpsol_out(i), 1), 1)

    def eval(self, arg: Sequence[ca.DM]) -> list[Any]:
        self._on_iteration(self._count, self._stats)
        self._count += 1
        return [0]
