"""M⁻¹ Jᵀ by the root's subtrees against the dense inverse of the inertia matrix."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ucontrol.model.root_subtrees import SMALLEST_NV, RootSubtrees

_INERTIAL = (
    '<inertial><mass value="1.3"/>'
    '<inertia ixx="0.02" ixy="0.001" ixz="0" iyy="0.03" iyz="0.002" izz="0.04"/></inertial>'
)
_LIMIT = '<limit lower="-3" upper="3" effort="1" velocity="1"/>'


def _forest(lengths: list[int]) -> pin.Model:
    """Chains of revolute and prismatic joints on the root, one of each given length."""
    parts = ['<?xml version="1.0"?><robot name="forest"><link name="base"/>']
    for c, length in enumerate(lengths):
        parent = "base"
        for k in range(length):
            kind, axis = ("revolute", "0 1 1") if k % 2 else ("prismatic", "1 0 0.5")
            child = f"c{c}l{k}"
            parts.append(
                f'<joint name="c{c}j{k}" type="{kind}"><parent link="{parent}"/>'
                f'<child link="{child}"/><origin xyz="0.3 0.1 {0.2 * k}"/>'
                f'<axis xyz="{axis}"/>{_LIMIT}</joint><link name="{child}">{_INERTIAL}</link>'
            )
            parent = child
    parts.append("</robot>")
    return pin.buildModelFromXML("".join(parts))


def _factorized(model: pin.Model, seed: int) -> tuple[pin.Data, np.ndarray]:
    """Data holding the Cholesky factors of M at a random q, and M (symmetric), (nv, nv)."""
    data = model.createData()
    q = np.random.default_rng(seed).uniform(-1.0, 1.0, model.nq)
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    pin.cholesky.decompose(model, data)
    return data, M


def test_blocks_give_the_dense_product() -> None:
    """Subtrees of 1, 2, 3 and 5 columns (mixed order): M⁻¹ Jᵀ as inv(M) @ Jᵀ."""
    model = _forest([2, 3, 2, 1, 5, 2, 3, 2, 1, 3, 2])
    assert model.nv >= SMALLEST_NV
    subtrees = RootSubtrees(model)
    assert subtrees.blocked
    assert sorted(len(group[0]) for group in subtrees.groups) == [1, 2, 3, 5]
    data, M = _factorized(model, 0)
    J = np.random.default_rng(1).standard_normal((7, model.nv))
    J[:, np.random.default_rng(2).random(model.nv) < 0.6] = 0.0  # sparse rows as contacts'
    product = subtrees.inverse_inertia_rows(pin.cholesky.computeMinv(model, data), J)
    expected = np.linalg.solve(M, J.T)
    assert np.allclose(product, expected, rtol=0.0, atol=1e-12 * np.abs(expected).max())


def test_one_subtree_or_few_columns_keep_the_dense_product() -> None:
    """One chain, or a forest below SMALLEST_NV columns: not blocked, the dense product."""
    for lengths in ([SMALLEST_NV + 2], [2, 2, 2], [2, SMALLEST_NV]):
        model = _forest(lengths)
        subtrees = RootSubtrees(model)
        assert not subtrees.blocked
        data, M = _factorized(model, 3)
        J = np.random.default_rng(4).standard_normal((3, model.nv))
        Minv = pin.cholesky.computeMinv(model, data)
        assert np.array_equal(subtrees.inverse_inertia_rows(Minv, J), Minv @ J.T)
        assert np.allclose(Minv @ J.T, np.linalg.solve(M, J.T), atol=1e-9)
