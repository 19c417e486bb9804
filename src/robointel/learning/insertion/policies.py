"""Insertion policies by name: the learned skills' and the baselines they are measured against.

:data:`STRATEGIES` names every insertion strategy the robot cell runs (:func:`strategy_policy`):
``felt`` (the feel-align-insert strategy with the rotation learned from the person, :class:`FeltSkill`; the
skill the learning benchmark measures), ``gmr`` (the GMR wrench -> corrective twist skill of Sec. 5.5,
:class:`InsertionSkill`), ``constant-push`` and ``hand-tuned`` (the compliant controller without a learned
skill) and ``position-only`` (the stiff joint servo pushing along the tool axis, no force feedback).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.learning.insertion.felt_skill import FeltSkill
from robointel.learning.insertion.skill import InsertionSkill

#: the insertion strategies by name: the learned ones first, then the baselines
STRATEGIES = ("felt", "gmr", "constant-push", "hand-tuned", "position-only")
#: robot time (s) a trial of each strategy gets: the felt skill feels the face, turns square and inserts in
#: 11-12 s (the learning benchmark's median 11.6 s, 50 of 50 within 15 s); the others push in from the start
TIME_LIMIT_S = {"felt": 15.0, "gmr": 10.0, "constant-push": 10.0, "hand-tuned": 10.0, "position-only": 10.0}


@dataclass(frozen=True)
class ConstantPush:
    """The compliant controller without a skill: a constant axial speed, the equilibrium left where it is.

    Attributes:
        speed: Axial speed of the force-limited damper (m/s).
    """

    speed: float = 0.008

    def __call__(self, wrench: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Tool twist [0, 0, speed, 0, 0] whatever the wrench (6,)."""
        return np.array([0.0, 0.0, self.speed, 0.0, 0.0])


@dataclass(frozen=True)
class HandTunedAdmittance:
    """A hand-tuned linear admittance: the corrective twist is proportional to the felt wrench.

    With the torque about the compliance centre tau_c = tau - c z x f (the sensor's torque moved ``centre``
    metres down the tool axis), all in the tool frame::

        twist = [k_f fx, k_f fy, speed * clip(1 - |fz| / f_slow, 0, 1), k_t tau_c,x, k_t tau_c,y]

    the equilibrium yields to lateral forces and turns with the torque about the centre (the rotation that
    relieves it), and the push slows as the axial force grows.

    Attributes:
        k_force: Lateral admittance (m/s per N).
        k_torque: Rotational admittance (rad/s per N m) about the compliance centre.
        speed: Free axial speed (m/s).
        f_slow: Axial force (N) at which the push stops.
        centre: Distance (m) from the F/T sensor to the compliance centre along the tool axis.
    """

    k_force: float = 1e-3
    k_torque: float = 0.1
    speed: float = 0.008
    f_slow: float = 10.0
    centre: float = 0.0

    def __call__(self, wrench: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Tool twist (5,) [m/s, rad/s] for the felt wrench (6,) [N, N m] in the tool frame."""
        w = np.asarray(wrench, float)
        slow = float(np.clip(1.0 - abs(w[2]) / self.f_slow, 0.0, 1.0))
        tx, ty = w[3] + self.centre * w[1], w[4] - self.centre * w[0]
        return np.array([self.k_force * w[0], self.k_force * w[1], self.speed * slow,
                         self.k_torque * tx, self.k_torque * ty])


def skill_policy(skill: FeltSkill | InsertionSkill, centre: float) -> Any:
    """The robot cell's insertion policy of a fitted skill (a fresh one per trial).

    Args:
        skill: A fitted :class:`FeltSkill` (its stage machine with the learned rotation, proprioceptive) or
            :class:`InsertionSkill` (its GMR, wrench -> twist).
        centre: Distance (m) from the F/T sensor to the ball tip's centre on the robot's tool.

    Returns:
        The policy for :meth:`~robointel.learning.insertion.RobotCell.insert`.

    Raises:
        InvalidInput: ``skill`` is neither, or not fitted.
    """
    if isinstance(skill, FeltSkill) and hasattr(skill, "params_"):
        return skill.policy(centre)
    if isinstance(skill, InsertionSkill) and hasattr(skill, "x_mean_"):
        return skill.policy()
    raise InvalidInput(f"an insertion policy needs a fitted FeltSkill or InsertionSkill, got {type(skill).__name__}",
                       value=type(skill).__name__)


def baseline_policy(name: str, centre: float) -> Any:
    """The policy of a baseline strategy by name (``constant-push`` or ``hand-tuned``).

    Args:
        name: The strategy's name.
        centre: Distance (m) from the F/T sensor to the compliance centre along the tool axis.

    Returns:
        The policy for :meth:`~robointel.learning.insertion.RobotCell.insert`.

    Raises:
        InvalidInput: Not a baseline's name.
    """
    if name == "constant-push":
        return ConstantPush()
    if name == "hand-tuned":
        return HandTunedAdmittance(centre=centre)
    raise InvalidInput(f"unknown baseline {name!r}: use 'constant-push' or 'hand-tuned'", value=name)
