"""scipy's LAPACK wrappers loaded without ``scipy.linalg``: the same routines, bit for bit."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.linalg.lapack

from ucontrol.solvers import lapack_routines
from ucontrol.solvers.lapack_routines import lapack_routine


def _symmetric(seed: int, n: int) -> np.ndarray:
    A = np.random.default_rng(seed).standard_normal((n, n))
    return A @ A.T


@pytest.mark.parametrize("n", [2, 3, 7])
def test_dsyev_is_scipys_bit_for_bit(n: int) -> None:
    A = _symmetric(n, n)
    ours = lapack_routine("dsyev")(A)
    reference = scipy.linalg.lapack.dsyev(A)
    for mine, theirs in zip(ours, reference, strict=True):
        np.testing.assert_array_equal(mine, theirs)
    values, vectors, info = ours
    assert info == 0
    np.testing.assert_allclose(vectors @ np.diag(values) @ vectors.T, A, atol=1e-12 * n)


def test_without_the_extension_file_falls_back_on_scipy_linalg(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(lapack_routines, "_flapack_file", lambda: None)
    monkeypatch.delitem(sys.modules, lapack_routines.FLAPACK)  # as if never imported
    module = lapack_routines._flapack.__wrapped__()
    assert module is scipy.linalg.lapack
    assert module.dsyev is scipy.linalg.lapack.dsyev


def test_unknown_routine_raises() -> None:
    with pytest.raises(AttributeError, match="not_a_routine"):
        lapack_routine("not_a_routine")


def test_loading_a_routine_imports_no_scipy_package() -> None:
    """In a new process: ``dsyev`` loaded and called, scipy's packages never imported.

    The extension module is there under its own name (which ``scipy.linalg``, imported later,
    takes as it is: the same functions).
    """
    program = (
        "import sys, numpy as np\n"
        "from ucontrol.solvers.lapack_routines import lapack_routine\n"
        "w, v, info = lapack_routine('dsyev')(np.diag([2.0, 1.0]))\n"
        "assert info == 0 and w.tolist() == [1.0, 2.0], (w, info)\n"
        "print(' '.join(m for m in sys.modules if m == 'scipy' or m.startswith('scipy.')))\n"
    )
    assert _printed(program) == [lapack_routines.FLAPACK]


def test_scipy_linalg_imported_later_takes_the_loaded_module() -> None:
    program = (
        "from ucontrol.solvers.lapack_routines import lapack_routine\n"
        "dsyev = lapack_routine('dsyev')\n"
        "import scipy.linalg.lapack\n"
        "print(scipy.linalg.lapack.dsyev is dsyev)\n"
    )
    assert _printed(program) == ["True"]


def _printed(program: str) -> list[str]:
    """The words ``program`` printed, run in a new process."""
    completed = subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, timeout=60
    )
    assert completed.returncode == 0, completed.stderr
    return completed.stdout.split()
