"""The loop closed at the hand: what the cameras and the gripper's own sensors say about a grasp.

Three checks, each on what a real cell has (the perceived cloud, the finger encoders and the pads'
contact forces), none on the simulator's knowledge of where the part is:

* before closing (:func:`between_jaws`): the perceived cloud has the part between the open jaws at the
  grasp pose the arm is about to reach (the pose measured at the pre-grasp, carried along the approach),
  and nothing where a finger goes: a plan made on the template's completion, or a pose the arm did not
  reach, would close on air or push the part away;
* after closing (:func:`after_close`): the jaw opening and the two pads' contact forces tell a firm grip
  from an empty hand (the jaws met) or a partial one (a pad without force, or jaws far narrower than
  the part measured where they closed: a tip, a corner, a part squeezed out);
* after the lift (:func:`after_lift`): the opening or the pad forces changed since the close: the part
  slid or turned in the jaws, or fell.

Each failed check sends the trial back to the cameras for another attempt
(:func:`robointel.learning.grasp.grasp_trial`, ``attempts``).
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from robointel.learning.grasp.quality import ParallelGripper
from robointel.learning.grasp.transfer import Grasp

__all__ = ["EMPTY_OPENING", "HandReading", "HandVerdict", "between_jaws", "read_hand", "after_close", "after_lift"]

#: Opening (m) under which the jaws are taken to have met: nothing between them.
EMPTY_OPENING = 0.0015


@dataclass(frozen=True)
class HandReading:
    """The gripper's sensors: jaw ``opening`` (m) and the normal ``forces`` (N) on the two pads."""

    opening: float
    forces: tuple[float, float]


@dataclass(frozen=True)
class HandVerdict:
    """A check's answer.

    ``ok`` and, when not, ``state`` ("empty", "partial", "slipped", "not between the jaws", "finger on
    the part") and ``detail`` in words.
    """

    ok: bool
    state: str
    detail: str = ""


def between_jaws(grasp: Grasp, observed: npt.ArrayLike, gripper: ParallelGripper, *, min_points: int = 3,
                 clearance: float = 0.001) -> HandVerdict:
    """Whether the perceived part lies between the open jaws at ``grasp`` and clear of the fingers.

    Args:
        grasp: The grasp frame the jaws will close at (world).
        observed: The perceived cloud (n, 3), m, world (only what the cameras saw).
        gripper: The jaws (opening, pad breadth and depth, finger thickness).
        min_points: Perceived points needed in the closing region (the box between the pads: the pad
            breadth, the opening less ``clearance`` on each side, the pads' depth along the approach).
        clearance: Margin (m) of the finger boxes (a perceived point inside a finger grown by it: the
            finger would hit the part on the way down).

    Returns:
        ``ok`` when at least ``min_points`` perceived points lie in the closing region, centred on the
        pads (their mean within a quarter of the pad breadth of the pads' middle: jaws that would
        close on the part's very end or beside it are not between the jaws) and none in a finger's
        box; else the state "not between the jaws" or "finger on the part".
    """
    P = np.asarray(observed, float)
    rel = (P - grasp.centre) @ grasp.rotation
    half = gripper.max_width / 2
    depth = (rel[:, 2] <= gripper.tip_depth) & (rel[:, 2] >= gripper.tip_depth - gripper.finger_length)
    across = np.abs(rel[:, 0]) < gripper.finger_breadth / 2
    inside = depth & across & (np.abs(rel[:, 1]) < half - clearance)
    n_in = int(np.count_nonzero(inside))
    for c, size in gripper.boxes()[:2]:
        if np.any(np.all(np.abs(rel - c) <= size / 2 + clearance, axis=1)):
            return HandVerdict(False, "finger on the part", f"a perceived point lies where a finger goes "
                                                            f"({n_in} between the jaws)")
    if n_in < min_points:
        return HandVerdict(False, "not between the jaws",
                           f"{n_in} perceived points between the jaws (need {min_points})")
    off = float(rel[inside, 0].mean())
    if abs(off) > gripper.finger_breadth / 4:
        return HandVerdict(False, "not between the jaws",
                           f"the perceived part lies {off * 1e3:+.1f} mm off the pads' middle")
    return HandVerdict(True, "between the jaws", f"{n_in} perceived points between the jaws")


def read_hand(m: mujoco.MjModel, d: mujoco.MjData, fingers: tuple[int, int], joint: int,
              gripper: ParallelGripper) -> HandReading:
    """The gripper's sensors in a MuJoCo scene: the jaw opening and each pad's summed contact normal force.

    Args:
        m: The model.
        d: Its data.
        fingers: Body ids of the two fingers (the pads' bodies).
        joint: Id of a finger's slide joint (travel from open, m; the fingers move together).
        gripper: The jaws (their full opening).

    Returns:
        The :class:`HandReading`: opening ``max_width - 2 travel`` (m); per finger the normal force of its
        contacts with anything but the other finger (N): what pressure pads on the jaws would read.
    """
    f6 = np.zeros(6)
    forces = [0.0, 0.0]
    for i in range(d.ncon):
        c = d.contact[i]
        b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
        for k, fb in enumerate(fingers):
            if (b1 == fb) != (b2 == fb) and {b1, b2} != set(fingers):
                mujoco.mj_contactForce(m, d, i, f6)
                forces[k] += abs(float(f6[0]))
    opening = float(gripper.max_width - 2 * d.qpos[m.jnt_qposadr[joint]])
    return HandReading(opening, (forces[0], forces[1]))


def after_close(reading: HandReading, expected_width: float, gripper: ParallelGripper, *,
                force_share: float = 0.25, narrow: float = 0.5, slack: float = 0.004) -> HandVerdict:
    """Tell a grip from an empty or a partial one after the jaws closed.

    Args:
        reading: The sensors after closing.
        expected_width: The part's width between the planned contacts (m).
        gripper: The jaws (``grip_force`` per finger).
        force_share: Each pad must press with at least this share of the grip force.
        narrow: An opening under ``narrow * expected_width - slack`` is partial: the jaws closed well
            inside the part as measured (on a tip or a corner of it, or it was pushed out).
        slack: See ``narrow`` (m; the cloud's 5 mm voxels).

    Returns:
        ``ok``, or the state "empty" (the jaws met, or no pad force at all) or "partial".
    """
    f_min = force_share * gripper.grip_force
    if reading.opening < EMPTY_OPENING or max(reading.forces) < f_min:
        return HandVerdict(False, "empty", f"jaws at {reading.opening * 1e3:.1f} mm, pad forces "
                                           f"{reading.forces[0]:.1f} / {reading.forces[1]:.1f} N")
    if min(reading.forces) < f_min:
        return HandVerdict(False, "partial", f"one pad without force ({reading.forces[0]:.1f} / "
                                             f"{reading.forces[1]:.1f} N)")
    if np.isfinite(expected_width) and reading.opening < narrow * expected_width - slack:
        return HandVerdict(False, "partial", f"jaws at {reading.opening * 1e3:.1f} mm on a part planned "
                                             f"{expected_width * 1e3:.1f} mm wide")
    return HandVerdict(True, "held", f"jaws at {reading.opening * 1e3:.1f} mm")


def after_lift(closed: HandReading, lifted: HandReading, gripper: ParallelGripper, *, share: float = 0.5,
               force_share: float = 0.25) -> HandVerdict:
    """Tell a slip after the lift: the jaws met or closed by half, or a pad lost its force, since the close.

    A part held off its centre of mass turns in the jaws as it leaves the table until the pads' friction
    carries it, and the jaws close by a few millimetres on its new section: on tuning seed 7 toy arms
    closed by 2-9 mm (up to 24 % of the opening) and cups on their rim by up to 29 %, and were held
    through the shake. So a moderate closing is no slip; the jaws closing by ``share`` of their opening
    (a part sliding out from between the pads), meeting, or a pad losing its force is.

    Args:
        closed: The sensors after closing (on the table).
        lifted: The sensors after the lift.
        gripper: The jaws (``grip_force`` per finger).
        share: Closing, as a share of the opening after closing, that counts as a slip.
        force_share: Each pad must still press with this share of the grip force.

    Returns:
        ``ok``, or the state "slipped" (or "empty" when the jaws met).
    """
    if lifted.opening < EMPTY_OPENING:
        return HandVerdict(False, "empty", f"the jaws met in the lift ({lifted.opening * 1e3:.1f} mm)")
    if closed.opening - lifted.opening > share * closed.opening:
        return HandVerdict(False, "slipped", f"the jaws closed from {closed.opening * 1e3:.1f} to "
                                             f"{lifted.opening * 1e3:.1f} mm in the lift")
    if min(lifted.forces) < force_share * gripper.grip_force:
        return HandVerdict(False, "slipped", f"a pad lost its force in the lift ({lifted.forces[0]:.1f} / "
                                             f"{lifted.forces[1]:.1f} N)")
    return HandVerdict(True, "held", f"jaws at {lifted.opening * 1e3:.1f} mm")
