r"""Targeted mutants of the core rules, and which of them the test suite kills.

Each mutant changes one expression of a rule the physics depends on — the restitution law,
the active-set rule, the energy guard, the friction cone, the force feedback, the Zeno rule
and the LCP polish — in a copy of the committed sources (``git archive HEAD``, so that work
in progress in the checkout does not count), then runs the tests that guard the rule. A mutant
is *killed* when a test fails (or the run overruns its bound), *survives* when every test
passes. A surviving mutant is either a gap of the suite or equivalent (it changes no result);
``docs/testing.md`` says which.

Run: ``python experiments/mutation_check.py`` (about 15 min on two cores); ``--only NAME``
for some mutants, ``--list`` to see them. Writes ``docs/figures/mutation_check.md`` (``--out``).
Not run in CI: it runs parts of the suite once per mutant.
"""

from __future__ import annotations

import argparse
import io
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

ED = "ucontrol/integrators/event_driven.py"
MJ = "ucontrol/integrators/moreau_jean.py"
STAGES = "ucontrol/integrators/step_stages.py"
COULOMB = "ucontrol/solvers/proxsuite_coulomb.py"
REFINE = "ucontrol/solvers/lcp_refinement.py"
BROGLIATO = "ucontrol/control/brogliato_controller.py"
FLEXIBLE = "ucontrol/control/flexible_brogliato_controller.py"

ED_TESTS = ("tests/integrators/test_zeno_rule.py", "tests/integrators/test_event_driven.py")
MJ_TESTS = (
    "tests/integrators/test_active_set_prediction.py",
    "tests/test_bouncing_ball.py",
    "tests/extreme/test_restitution_limits.py",
    "tests/extreme/test_redundant_contacts.py",
    "tests/test_simulate.py",
)
COULOMB_TESTS = (
    "tests/solvers/test_fallbacks.py",
    "tests/solvers/test_proxsuite_coulomb.py",
    "tests/integrators/test_friction.py",
)
LCP_TESTS = (
    "tests/solvers/test_fallbacks.py",
    "tests/solvers/test_proxsuite_lcp.py",
    "tests/extreme/test_redundant_contacts.py",
)
LZB = "ucontrol/integrators/lzb_impact.py"
LZB_TESTS = ("tests/integrators/test_lzb_impact.py", "tests/integrators/test_lzb_event_driven.py")
SICONOS_TESTS = ("tests/integrators/test_siconos_convention.py",)
START_TESTS = ("tests/integrators/test_contacts_at_start.py",)
PERSISTENCE_TESTS = (
    "tests/closed_loop/test_two_constraints.py",
    "tests/integrators/test_friction.py",
    "tests/test_bouncing_ball.py",
)
FEEDBACK_TESTS = (
    "tests/closed_loop/test_robustness.py::test_force_feedback_divides_the_force_error_by_one_plus_kf",
    "tests/closed_loop/test_one_constraint.py",
)


@dataclass(frozen=True)
class Mutant:
    """One textual change of one rule.

    Attributes:
        name: Short identifier.
        rule: The core rule it breaks.
        path: Source file, relative to the repository.
        old: Text replaced; must occur exactly once in the file.
        new: Its replacement.
        tests: Test files run against it.
    """

    name: str
    rule: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


MUTANTS = (
    Mutant(
        "ed-newton-half-e",
        "restitution law",
        ED,
        "return self.impact_solver.solve(terms.delassus(), (1.0 + e) * u_minus)",
        "return self.impact_solver.solve(terms.delassus(), (1.0 + 0.5 * e) * u_minus)",
        ED_TESTS,
    ),
    Mutant(
        "mj-newton-half-e",
        "restitution law",
        STAGES,
        "rebound = ops.where(no_rebound, 0.0, restitution * u_minus)",
        "rebound = ops.where(no_rebound, 0.0, 0.5 * restitution * u_minus)",
        MJ_TESTS,
    ),
    Mutant(
        "mj-no-prediction",
        "active-set rule",
        STAGES,
        "return gap + horizon * normal_velocity",
        "return gap + 0.0 * normal_velocity",
        MJ_TESTS,
    ),
    Mutant(
        "mj-horizon-one-step",
        "active-set rule",
        MJ,
        "gamma = 0.5  # active-set prediction horizon, in steps",
        "gamma = 1.0  # active-set prediction horizon, in steps",
        MJ_TESTS,
    ),
    Mutant(
        "ed-closed-without-speed",
        "active-set rule",
        ED,
        "closed = (gap <= self.closure_gap) & (np.abs(u) <= self.closure_velocity)",
        "closed = gap <= self.closure_gap",
        ED_TESTS,
    ),
    Mutant(
        "mj-energy-guard-off",
        "energy guard",
        STAGES,
        "return gain > ENERGY_GAIN_TOLERANCE * (1.0 + kinetic_energy)",
        "return 0.0 * gain > 1.0",
        MJ_TESTS,
    ),
    Mutant(
        "mj-energy-guard-sign",
        "energy guard",
        STAGES,
        "- theta * (u_free - u_k))",
        "+ theta * (u_free - u_k))",
        MJ_TESTS,
    ),
    Mutant(
        "coulomb-cone-doubled",
        "friction cone",
        COULOMB,
        "step = problem.mu * P[:m] - thresholds  # the Tresca map, from the QP's impulses",
        "step = 2.0 * problem.mu * P[:m] - thresholds  # the Tresca map, from the QP's impulses",
        COULOMB_TESTS,
    ),
    Mutant(
        "coulomb-cone-halved-start",
        "friction cone",
        COULOMB,
        "thresholds, previous_step = problem.mu * P[:m], np.zeros(m)",
        "thresholds, previous_step = 0.5 * problem.mu * P[:m], np.zeros(m)",
        COULOMB_TESTS,
    ),
    Mutant(
        "feedback-sign",
        "force feedback",
        BROGLIATO,
        "-lambda_d + self.gains.force_gain * (\n                measured - lambda_d\n            )",
        "-lambda_d + self.gains.force_gain * (\n                lambda_d - measured\n            )",
        FEEDBACK_TESTS,
    ),
    Mutant(
        "feedback-off",
        "force feedback",
        BROGLIATO,
        "-lambda_d + self.gains.force_gain * (\n                measured - lambda_d\n            )",
        "-lambda_d + 0.0 * (\n                measured - lambda_d\n            )",
        FEEDBACK_TESTS,
    ),
    Mutant(
        "feedback-sign-interpreted",
        "force feedback",
        BROGLIATO,
        "tau += J_c.T @ (-lambda_d + gains.force_gain * (force - lambda_d))",
        "tau += J_c.T @ (-lambda_d + gains.force_gain * (lambda_d - force))",
        ("tests/closed_loop/test_interpreted_law.py",),
    ),
    Mutant(
        "feedback-sign-flexible",
        "force feedback",
        FLEXIBLE,
        "force_term = -lambda_d + self.gains.force_gain * (lambda_m - lambda_d)",
        "force_term = -lambda_d + self.gains.force_gain * (lambda_d - lambda_m)",
        ("tests/closed_loop/test_flexible_cycles.py",),
    ),
    Mutant(
        "zeno-rebound-without-e",
        "Zeno rule",
        ED,
        "bounces = (u_minus < 0.0) & (-restitution * u_minus >= self.zeno_velocity)",
        "bounces = (u_minus < 0.0) & (-u_minus >= self.zeno_velocity)",
        ED_TESTS,
    ),
    Mutant(
        "zeno-capture-half",
        "Zeno rule",
        ED,
        "slow = (u > self.closure_velocity) & (u < self.zeno_velocity)",
        "slow = (u > self.closure_velocity) & (u < 0.5 * self.zeno_velocity)",
        ED_TESTS,
    ),
    Mutant(
        "zeno-capture-adds-none",
        "Zeno rule",
        ED,
        "approaching = ~captured & (u < -self.closure_velocity)",
        "approaching = np.zeros_like(captured)",
        ED_TESTS,
    ),
    Mutant(
        "polish-keeps-worse",
        "LCP polish",
        REFINE,
        "if candidate_residual <= residual:",
        "if candidate_residual > residual:",
        LCP_TESTS,
    ),
    Mutant(
        "polish-off",
        "LCP polish",
        REFINE,
        "if polish and residual > POLISH_THRESHOLD:",
        "if False:",
        LCP_TESTS,
    ),
    Mutant(
        "lemke-fallback-off",
        "LCP polish",
        REFINE,
        "if residual > residual_tolerance and b.size <= LEMKE_FALLBACK_SIZE:",
        "if False:",
        LCP_TESTS,
    ),
    Mutant(
        "lzb-restitution-not-squared",
        "restitution law",
        LZB,
        "self.inverse_e2 = 1.0 / np.maximum(e, 1e-150) ** 2",
        "self.inverse_e2 = 1.0 / np.maximum(e, 1e-150) ** 1",
        LZB_TESTS,
    ),
    Mutant(
        "lzb-hertz-as-linear",
        "restitution law",
        LZB,
        "return self.kappa * np.maximum(s, 0.0) ** self.eta",
        "return self.kappa * np.maximum(s, 0.0)",
        LZB_TESTS,
    ),
    Mutant(
        "mj-restitution-on-separating",
        "restitution law",
        STAGES,
        "ops.logical_or(held_open, u_minus >= -threshold)",
        "ops.logical_or(held_open, u_minus >= np.inf)",
        (*SICONOS_TESTS, *MJ_TESTS),
    ),
    Mutant(
        "mj-siconos-closing-only",
        "restitution law",
        STAGES,
        "no_rebound = held_open if siconos else",
        "no_rebound = ops.logical_or(held_open, u_minus >= 0.0) if siconos else",
        SICONOS_TESTS,
    ),
    Mutant(
        "mj-start-rule-off",
        "active-set rule",
        STAGES,
        "START_GAP_TOLERANCE = 1e-9",
        "START_GAP_TOLERANCE = -1.0",
        START_TESTS,
    ),
    Mutant(
        "mj-persistence-off",
        "active-set rule",
        MJ,
        "self.persistence_tolerance = as_float(",
        "self.persistence_tolerance = 0.0 * as_float(",
        PERSISTENCE_TESTS,
    ),
    Mutant(
        "mj-held-closure-off",
        "active-set rule",
        STAGES,
        "closure = ops.where(held_open, gap / h, 0.0)",
        "closure = ops.where(held_open, 0.0 * gap, 0.0)",
        (*START_TESTS, *PERSISTENCE_TESTS),
    ),
    Mutant(
        "ed-closure-velocity-loose",
        "active-set rule",
        ED,
        "closure_velocity = 1e-9",
        "closure_velocity = 1e-3",
        ED_TESTS,
    ),
    Mutant(
        "mj-guard-redo-keeps-rebound",
        "energy guard",
        MJ,
        "solution, plastic = self._solve(D, b, indices, tangents, m_b), True",
        "solution, plastic = self._solve(D, b + rebound, indices, tangents, m_b), True",
        MJ_TESTS,
    ),
    Mutant(
        "mj-guard-tolerance-loose",
        "energy guard",
        STAGES,
        "ENERGY_GAIN_TOLERANCE = 1e-12",
        "ENERGY_GAIN_TOLERANCE = 1e-3",
        MJ_TESTS,
    ),
    Mutant(
        "coulomb-one-sided-box",
        "friction cone",
        COULOMB,
        "lower[rows] = -thresholds[planar]",
        "lower[rows] = 0.0 * thresholds[planar]",
        COULOMB_TESTS,
    ),
    Mutant(
        "coulomb-spatial-one-axis",
        "friction cone",
        COULOMB,
        "C[facet_rows, tangent_rows[:, 1, None]] = normals[..., 1]",
        "C[facet_rows, tangent_rows[:, 1, None]] = 0.0 * normals[..., 1]",
        COULOMB_TESTS,
    ),
    Mutant(
        "desired-force-sign",
        "force feedback",
        BROGLIATO,
        "-lambda_d + self.gains.force_gain * (\n                measured - lambda_d\n            )",
        "+lambda_d + self.gains.force_gain * (\n                measured - lambda_d\n            )",
        FEEDBACK_TESTS,
    ),
    Mutant(
        "feedback-gain-halved",
        "force feedback",
        BROGLIATO,
        "-lambda_d + self.gains.force_gain * (\n                measured - lambda_d\n            )",
        "-lambda_d + 0.5 * self.gains.force_gain * (\n"
        "                measured - lambda_d\n            )",
        FEEDBACK_TESTS,
    ),
    Mutant(
        "feedback-off-flexible",
        "force feedback",
        FLEXIBLE,
        "force_term = -lambda_d + self.gains.force_gain * (lambda_m - lambda_d)",
        "force_term = -lambda_d + 0.0 * (lambda_m - lambda_d)",
        ("tests/closed_loop/test_flexible_cycles.py",),
    ),
    Mutant(
        "zeno-threshold-doubled",
        "Zeno rule",
        ED,
        "bounces = (u_minus < 0.0) & (-restitution * u_minus >= self.zeno_velocity)",
        "bounces = (u_minus < 0.0) & (-restitution * u_minus >= 2.0 * self.zeno_velocity)",
        ED_TESTS,
    ),
    Mutant(
        "zeno-lzb-accumulation-off",
        "Zeno rule",
        ED,
        "if np.max(-restitution * u_minus) < self.zeno_velocity:  # an accumulation: plastic",
        "if False:  # an accumulation: plastic",
        (*ED_TESTS, *LZB_TESTS),
    ),
    Mutant(
        "polish-complement-set",
        "LCP polish",
        REFINE,
        "candidate = _solve_on_active_set(D, b, scale * impulses > velocity)",
        "candidate = _solve_on_active_set(D, b, scale * impulses < velocity)",
        LCP_TESTS,
    ),
    Mutant(
        "lemke-keeps-worse",
        "LCP polish",
        REFINE,
        "if pivoted is not None and pivoted.residual < residual:",
        "if pivoted is not None and pivoted.residual > residual:",
        LCP_TESTS,
    ),
)


#: Mutants shown to change no result (the reasons are in docs/testing.md).
EQUIVALENT = frozenset({"ed-closed-without-speed", "coulomb-cone-halved-start"})


@dataclass(frozen=True)
class Outcome:
    """What the tests did to one mutant.

    Attributes:
        mutant: The mutant.
        killed: A test failed, or the run overran its bound.
        seconds: Wall time of the test run in [s].
        detail: The first failing test, or the last line of pytest's output.
    """

    mutant: Mutant
    killed: bool
    seconds: float
    detail: str


def snapshot(folder: Path) -> None:
    """Extract the committed tree of the repository (``git archive HEAD``) into ``folder``."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "HEAD"], capture_output=True, check=True
    ).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")


def run_tests(tree: Path, tests: Sequence[str], timeout: float) -> tuple[bool, float, str]:
    """Run ``tests`` in ``tree`` (its own ``ucontrol`` first on the path), stopping at a failure.

    Returns:
        Whether every test passed, the wall time in [s], and a line describing the result.
    """
    command = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    start = time.perf_counter()
    process = subprocess.Popen(
        command,
        cwd=tree,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        output, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, 9)
        process.communicate()
        return False, time.perf_counter() - start, f"overran {timeout:g} s"
    seconds = time.perf_counter() - start
    lines = output.strip().splitlines()
    failed = [line for line in lines if line.startswith(("FAILED", "ERROR"))]
    return process.returncode == 0, seconds, (failed[0] if failed else lines[-1] if lines else "")


def check(mutant: Mutant, tree: Path, timeout: float) -> Outcome:
    """Apply ``mutant`` in ``tree``, run its tests, restore the file."""
    path = tree / mutant.path
    original = path.read_text()
    if original.count(mutant.old) != 1:
        raise ValueError(
            f"{mutant.name}: the text to mutate occurs {original.count(mutant.old)} "
            f"times in {mutant.path}"
        )
    mutated = original.replace(mutant.old, mutant.new)
    compile(mutated, str(path), "exec")  # a mutant must be valid Python
    path.write_text(mutated)
    try:
        passed, seconds, detail = run_tests(tree, mutant.tests, timeout)
    finally:
        path.write_text(original)
    return Outcome(mutant, not passed, seconds, detail)


def markdown(outcomes: Sequence[Outcome]) -> str:
    """The results as a Markdown table with the kill rate."""
    killed = sum(o.killed for o in outcomes)
    survivors = [o.mutant.name for o in outcomes if not o.killed]
    unexplained = [name for name in survivors if name not in EQUIVALENT]
    judged = len(outcomes) - (len(survivors) - len(unexplained))
    lines = [
        f"Killed {killed} of {len(outcomes)} mutants ({100.0 * killed / len(outcomes):.1f} %); "
        f"{len(survivors) - len(unexplained)} survivors are equivalent (docs/testing.md), so "
        f"{killed} of the {judged} mutants that change a result are killed "
        f"({100.0 * killed / max(judged, 1):.1f} %).",
        *(f"Survivor not known to be equivalent: `{name}`." for name in unexplained),
        "",
        "| rule | mutant | file | killed | tests [s] | first failure |",
        "|---|---|---|:-:|---:|---|",
    ]
    for o in outcomes:
        detail = o.detail.replace("|", "\\|")[:110]
        lines.append(
            f"| {o.mutant.rule} | `{o.mutant.name}` | `{Path(o.mutant.path).name}` | "
            f"{'yes' if o.killed else '**no**'} | {o.seconds:.0f} | {detail} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> list[Outcome]:
    """Run the mutants and write the table; returns the outcomes."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=None, help="names of the mutants to run")
    parser.add_argument("--list", action="store_true", help="list the mutants and stop")
    parser.add_argument(
        "--timeout", type=float, default=900.0, help="bound of one mutant's test run, in [s]"
    )
    parser.add_argument(
        "--no-baseline",
        action="store_true",
        help="skip the run of every test set on the unmutated sources (they must pass)",
    )
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "mutation_check.md")
    args = parser.parse_args(argv)
    mutants = [m for m in MUTANTS if args.only is None or m.name in args.only]
    if args.list:
        for m in mutants:
            print(f"{m.name:28s} {m.rule:16s} {m.path}")
        return []
    with tempfile.TemporaryDirectory(prefix="ucontrol-mutants-") as folder:
        tree = Path(folder)
        snapshot(tree)
        if not args.no_baseline:
            for tests in sorted({m.tests for m in mutants}):
                passed, seconds, detail = run_tests(tree, tests, args.timeout)
                print(f"baseline {' '.join(tests)}: {detail} ({seconds:.0f} s)", flush=True)
                if not passed:
                    raise SystemExit("the unmutated sources fail their tests: no mutant is judged")
        outcomes = []
        for m in mutants:
            outcome = check(m, tree, args.timeout)
            verdict = "killed" if outcome.killed else "SURVIVED"
            print(f"{m.name}: {verdict} ({outcome.seconds:.0f} s) {outcome.detail}", flush=True)
            outcomes.append(outcome)
    table = markdown(outcomes)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(table)
    print(table)
    return outcomes


if __name__ == "__main__":
    main()
