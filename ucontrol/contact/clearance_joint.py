r"""A revolute joint with radial clearance: a journal in a bearing, as one unilateral constraint.

On a robot built by :func:`~ucontrol.model.joint_clearance.with_joint_clearance`, the joint's
play coordinates :math:`p = (x, y)` (the journal's centre relative to the bearing's, in the
joint's frame, in [m]) and its rotation :math:`\theta` (the journal relative to the bearing)
give (Brogliato, *Nonsmooth Mechanics*, §8.5.3):

.. math::

    g = c - \|p\|, \qquad n = p / \|p\|, \qquad
    u_n = \dot g = -n \cdot \dot p, \qquad
    u_t = t \cdot \dot p + R\,\dot\theta, \quad t = a \times n,

c the radial clearance, R the journal's radius: :math:`u_t` is the sliding velocity of the
journal's surface on the bearing's at the contact point :math:`(\|p\| + R)\,n` (of two
coincident points, the same in every frame). The constraint acts on the three coordinates of
the joint: its normal row is :math:`-n^T` on (x, y), its tangential row :math:`(t^T, R)` on
(x, y, θ), and its drift (:math:`\dot J v`) :math:`-(t \cdot \dot p)^2 / \|p\|`. With the
journal centred (:math:`p = 0`, gap c > 0) the normal is taken along :math:`e_1`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ucontrol._validation import as_in_interval, as_non_negative, as_positive


@dataclass(frozen=True, kw_only=True)
class ClearanceJoint:
    """Radial clearance of revolute joint ``joint`` (module docstring).

    Attributes:
        joint: Name of the revolute joint in the robot's description.
        clearance: Radial clearance c > 0 (bearing radius minus journal radius), in [m].
        journal_radius: Journal radius R >= 0, in [m] (the lever of the friction torque).
        restitution: Newton's coefficient of restitution in [0, 1].
        friction: Coulomb coefficient μ >= 0 between journal and bearing.
        name: Label of the constraint; default ``"<joint>/clearance"``.
    """

    joint: str
    clearance: float
    journal_radius: float = 0.0
    restitution: float = 0.0
    friction: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "clearance", as_positive("clearance", self.clearance))
        radius = as_non_negative("journal_radius", self.journal_radius)
        object.__setattr__(self, "journal_radius", radius)
        object.__setattr__(
            self, "restitution", as_in_interval("restitution", self.restitution, 0.0, 1.0)
        )
        object.__setattr__(self, "friction", as_non_negative("friction", self.friction))
        if not self.name:
            object.__setattr__(self, "name", f"{self.joint}/clearance")
