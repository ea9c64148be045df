r"""The inertia matrix as blocks, one per subtree of the root, and :math:`M^{-1} J^T` by block.

A kinematic tree whose root (the universe) carries several subtrees (a column of beads, each
on its own joints; several robots in one model) has a block-diagonal inertia matrix
:math:`M = \operatorname{diag}(M_1, \dots, M_K)`, one block per subtree's velocity columns, and
so has :math:`M^{-1}`. The product :math:`M^{-1} J^T` with r rows J then costs
:math:`\sum_k b_k^2 r` instead of :math:`n_v^2 r` (:math:`b_k` the blocks' sizes): 100 beads of
two joints each, 200 rows, :math:`1.6 \cdot 10^5` instead of :math:`8 \cdot 10^6`
multiplications. A robot on one subtree (an arm, a free-flying base with its legs) has one
block; it keeps the dense product.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

Vector = NDArray[np.float64]

#: Fewest velocity columns for which the blocks pay for their gathers (below: dense product).
SMALLEST_NV = 24


class RootSubtrees:
    """The velocity columns of each subtree of a model's root, grouped by block size.

    Args:
        model: The Pinocchio model.

    Attributes:
        groups: Per block size b, the columns of each block of that size, shape (K_b, b).
        blocked: Whether :meth:`inverse_inertia_rows` uses the blocks: more than one subtree,
            the largest at most half of nv, and nv >= :data:`SMALLEST_NV`.
    """

    def __init__(self, model: pin.Model) -> None:
        blocks: dict[int, list[int]] = {}  # first joint of each subtree -> its columns
        for j in range(1, model.njoints):
            top = model.supports[j][1]  # the joint below the universe on j's chain
            joint = model.joints[j]
            blocks.setdefault(top, []).extend(range(joint.idx_v, joint.idx_v + joint.nv))
        by_size: dict[int, list[list[int]]] = {}
        for columns in blocks.values():
            by_size.setdefault(len(columns), []).append(sorted(columns))
        self.groups = [np.array(columns, dtype=np.intp) for columns in by_size.values()]
        largest = max(by_size, default=0)
        self.blocked = len(blocks) > 1 and 2 * largest <= model.nv and model.nv >= SMALLEST_NV

    def inverse_inertia_rows(self, Minv: Vector, J: Vector) -> Vector:
        r""":math:`M^{-1} J^T` in [1/kg] (of rows J), shape (nv, r), from M⁻¹'s diagonal blocks.

        Args:
            Minv: The inverse inertia matrix, shape (nv, nv) (block diagonal by subtree).
            J: Rows, shape (r, nv).
        """
        if not self.blocked:
            return Minv @ J.T
        product = np.empty((J.shape[1], J.shape[0]))
        Jt = J.T
        for columns in self.groups:  # (K, b): K blocks of b columns
            blocks = Minv[columns[:, :, None], columns[:, None, :]]  # (K, b, b)
            product[columns] = np.matmul(blocks, Jt[columns])  # (K, b, r)
        return product
