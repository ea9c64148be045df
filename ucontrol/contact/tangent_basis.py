r"""Tangent directions of a contact, in which its friction impulse is written.

A spatial contact with unit normal :math:`n` has the orthonormal tangents :math:`t_1, t_2` with
:math:`t_1 \times t_2 = n` (:math:`t_1 = h \times n / \|h \times n\|`, h the world x axis, or
the y axis when n is close to x). A planar contact of a robot moving in the plane normal to the
unit axis a has the single tangent :math:`t = a \times n` (normalised), the direction of the
plane of motion along the surface.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Vector = NDArray[np.float64]

_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])


def tangent_basis(normal: Vector, planar_axis: Vector | None = None) -> Vector:
    """Unit tangents of contacts with unit ``normal`` (..., 3), shape (..., 2, 3), or (..., 1, 3).

    Args:
        normal: Unit contact normal in world coordinates, shape (3,), or one per contact
            (k, 3).
        planar_axis: Unit normal of the plane of motion, shape (3,), or None (spatial).
    """
    if planar_axis is not None:
        t = cross(planar_axis, normal)
        return (t / np.sqrt(np.einsum("...i,...i->...", t, t))[..., None])[..., None, :]
    helper = np.where((np.abs(normal[..., 0]) < 0.9)[..., None], _X, _Y)
    t1 = cross(helper, normal)
    t1 /= np.sqrt(np.einsum("...i,...i->...", t1, t1))[..., None]
    return np.stack((t1, cross(normal, t1)), axis=-2)


def cross(a: Vector, b: Vector) -> Vector:
    """Cross product of ``a`` (..., 3) and ``b`` (..., 3), broadcast, shape (..., 3).

    ``numpy.cross`` spends most of a call of this size in its argument handling (broadcast,
    axis moves); this is the contact hot path.
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    product = np.empty(np.broadcast_shapes(a.shape, b.shape))
    product[..., 0] = a1 * b2 - a2 * b1
    product[..., 1] = a2 * b0 - a0 * b2
    product[..., 2] = a0 * b1 - a1 * b0
    return product
