"""The continuation example of docs/stability.md runs as it stands and finds the flip."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from ucontrol.analysis import poincare as pc

PAGE = Path(__file__).resolve().parents[2] / "docs" / "stability.md"
#: The page's python block that follows the example's heading.
_EXAMPLE = re.compile(
    r"\*\*A continuation, step by step\.\*\*.*?^```python\n(?P<code>.*?)^```$", re.M | re.S
)


def test_continuation_example_finds_the_period_doubling(capsys: pytest.CaptureFixture) -> None:
    match = _EXAMPLE.search(PAGE.read_text(encoding="utf-8"))
    assert match is not None, "the example's python block is missing"
    namespace: dict[str, object] = {}
    exec(compile(match["code"], str(PAGE), "exec"), namespace)
    printed = capsys.readouterr().out
    expected = re.search(r"^# (?P<line>period_doubling at .*)$", match["code"], re.M)
    assert expected is not None and printed.strip() == expected["line"]
    branch, flip = namespace["branch"], namespace["flip"]
    assert isinstance(branch, pc.Branch) and isinstance(flip, pc.Bifurcation)
    assert branch.stopped == "period_doubling"
    # Independent of the saltation Jacobian the example uses: central finite differences of
    # the map at the flip have a multiplier at -1.
    system = pc.impact_oscillator(frequency=flip.parameter, **namespace["oscillator"])
    jacobian = pc.finite_difference_jacobian(pc.stroboscopic_map(system), flip.z)
    multipliers = np.linalg.eigvals(jacobian)
    assert np.min(np.abs(multipliers + 1.0)) <= 1e-5, multipliers
