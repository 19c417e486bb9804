"""The hold a grasp gives: can the jaws' friction carry the part through the lift and the shake?

Isotropy (6.20) scores a grasp's geometry; it does not know what the part weighs, where its centre of
mass lies or how the trial moves it. A parallel-jaw grip is weakest about its closing axis: a part held
off its centre of mass turns about the line between the pads, and only the friction inside the two
contact patches (soft-finger torsion) resists it. This module estimates the part (mass, centre of
mass) from the fitted template and rates each grasp by the margin of its friction over the load:

* the load: the part's weight and its inertia in the trial's shake (:class:`Shake`: J1 and J6
  oscillations), as a force and a torque at the grasp centre;
* the capacity: each pad presses with the gripper's ``grip_force``; a contact carries a tangential
  force ``f_t`` and a torsion ``tau`` about its normal while ``(f_t / (mu F))^2 + (tau / (mu_t F))^2 <= 1``
  (the elliptic soft-finger limit), ``mu_t = 2/3 mu a`` for a uniformly pressed disc of radius ``a``
  (the contact patch: how much of the part lies flat against the pad, see :func:`contact_patch`);
* the margin: the capacity over the load at the worst instant of the shake (> 1: the model says it
  holds; the planner asks for :data:`HOLD_TARGET`).

The friction coefficient is the planner's (0.5, as in (6.20)), below the simulated pads' 1.0: the
model is conservative on purpose (scanned surfaces, 5 mm voxels).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import ConvexHull, QhullError

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.learning.grasp.quality import ParallelGripper
from robointel.learning.grasp.transfer import Grasp

__all__ = ["GRAVITY", "HOLD_TARGET", "DENSITY", "Shake", "PartEstimate", "Hold", "contact_patch", "estimate_part",
           "hold", "hull_volume"]

#: Standard gravity (m/s^2).
GRAVITY = 9.81

#: The margin the planner asks of a grasp (capacity over peak load); below it the grasp pays a cost
#: (:meth:`Hold.cost`).
HOLD_TARGET = 2.0

#: Density (kg/m^3) assumed when a template carries no mass: the mass is this times the volume of the
#: fitted template's hull.
DENSITY = 400.0


@dataclass(frozen=True)
class Shake:
    """The trial's shake: J1 and J6 oscillate ``amplitude * sin(2 pi f t)`` together.

    Attributes:
        j1_amplitude: J1's amplitude (rad); J1 turns about the vertical axis through the robot base.
        j6_amplitude: J6's amplitude (rad); J6 turns about the flange axis, the approach of a grasp.
        frequency: Both oscillations' frequency (Hz).
    """

    j1_amplitude: float = 0.06
    j6_amplitude: float = 0.15
    frequency: float = 2.0

    def peak_acceleration(self, radius: float, amplitude: float) -> float:
        """Peak tangential acceleration (m/s^2) of a point ``radius`` m from an axis oscillating by ``amplitude``."""
        return float(amplitude * (2 * np.pi * self.frequency) ** 2 * radius)


@dataclass(frozen=True)
class PartEstimate:
    """What the planner believes of the part: ``mass`` (kg) and centre of mass ``com`` (3,) (m, world)."""

    mass: float
    com: np.ndarray


@dataclass(frozen=True)
class Hold:
    """A grasp's hold (see the module docstring).

    Attributes:
        margin: Capacity over the peak load (> 1: the friction model holds the part; inf: no load).
        lever: Distance (m) of the centre of mass from the closing axis.
        torque: Peak torque (N m) about the closing axis.
        force: Peak tangential force (N) on each pad (the weight and inertia, plus the couple of the
            torque about the other two axes).
        patch: Contact patch radius (m) used for the torsion (the smaller of the two pads').
    """

    margin: float
    lever: float
    torque: float
    force: float
    patch: float

    def cost(self, target: float = HOLD_TARGET) -> float:
        """The shortfall below ``target``: ``max(0, 1 - margin / target)``, in [0, 1]."""
        return float(max(0.0, 1.0 - self.margin / target))


def estimate_part(warped: npt.ArrayLike, *, mass: float | None = None, template_volume: float | None = None,
                  density: float = DENSITY) -> PartEstimate:
    """The part's mass and centre of mass from the template warped onto it.

    Args:
        warped: The template's surface points warped onto the part (k, 3), m, world frame (the fit's
            completion: the whole part, the sides the cameras miss included).
        mass: The template's mass (kg; None: ``density`` times the warped hull's volume).
        template_volume: The template's hull volume (m^3): with ``mass``, the part's mass is the
            template's scaled by the hull volume ratio (the warp's growth).
        density: Density (kg/m^3) used when ``mass`` is None.

    Returns:
        The estimate: the centre of mass is the warped surface points' centroid (a stand-in for the
        volume centroid).

    Raises:
        InvalidInput: fewer than 4 points, not finite, or a non-positive mass, volume or density.
    """
    W = as_array(warped, "warped template", (None, 3))
    if len(W) < 4:
        raise InvalidInput(f"estimate_part needs at least 4 points, got {len(W)}", value=len(W))
    for name, v in (("mass", mass), ("template_volume", template_volume), ("density", density)):
        if v is not None and not (np.isfinite(v) and v > 0):
            raise InvalidInput(f"estimate_part: {name} must be > 0, got {v}", value=v)
    vol = hull_volume(W)
    if mass is None:
        m = density * vol
    elif template_volume is not None and vol > 0:
        m = mass * float(np.clip(vol / template_volume, 0.25, 4.0))
    else:
        m = mass
    return PartEstimate(max(float(m), 1e-3), W.mean(axis=0))


def hull_volume(points: npt.ArrayLike) -> float:
    """Volume (m^3) of the convex hull of ``points`` (n, 3), m; 0 when they span no volume."""
    P = np.asarray(points, float)
    try:
        return float(ConvexHull(P).volume) if len(P) >= 4 else 0.0
    except (QhullError, ValueError):
        return 0.0


def contact_patch(cloud: npt.ArrayLike, grasp: Grasp, contact_offset: float, gripper: ParallelGripper, *,
                  slab: float = 0.004) -> float:
    """Radius (m) of the contact patch a pad makes with the part at one jaw.

    The part's points within ``slab`` (m) of the contact plane (the plane square to the closing axis at
    ``contact_offset`` m along it from the grasp centre) and inside the pad's face (its breadth and
    the pad's depth along the approach) are the patch; its radius is half its smaller extent (the
    largest disc it holds). A thin rim seen edge-on, a sphere's point or a jaw that meets the part only
    at its fingertip gives a small patch, a flat side square to the jaw a large one.

    Args:
        cloud: The part's points (n, 3), m, world frame.
        grasp: The grasp frame (x breadth, y closing axis, z approach).
        contact_offset: The contact's coordinate along the closing axis (m, from the grasp centre).
        gripper: The jaws (pad breadth, finger length, tip depth).
        slab: Thickness (m) of the slab about the contact plane (covers the 5 mm voxels).

    Returns:
        The patch radius (m), at least 0.5 mm (a point contact still has some patch).
    """
    P = np.asarray(cloud, float)
    rel = (P - grasp.centre) @ grasp.rotation
    z_lo = gripper.tip_depth - gripper.finger_length
    inside = (np.abs(rel[:, 1] - contact_offset) < slab) & (np.abs(rel[:, 0]) < gripper.finger_breadth / 2) & \
        (rel[:, 2] <= gripper.tip_depth) & (rel[:, 2] >= z_lo)
    if np.count_nonzero(inside) < 2:
        return 5e-4
    pts = rel[inside][:, [0, 2]]
    ext = np.ptp(pts, axis=0)
    return float(max(0.5 * float(ext.min()), 5e-4))


def hold(grasp: Grasp, contacts: npt.ArrayLike, cloud: npt.ArrayLike, part: PartEstimate, gripper: ParallelGripper,
         *, shake: Shake | None = None, mu: float = 0.5, base: npt.ArrayLike = (0.0, 0.0),
         directions: int = 16) -> Hold:
    """The hold of ``grasp`` on the part (see the module docstring).

    The load at the grasp centre is ``f = m (a + g)`` and ``tau = (com - centre) x f`` over the shake:
    ``a`` horizontal, of peak magnitude J1's tangential acceleration at the grasp (its distance from
    the base axis) plus J6's at the centre of mass (its distance from the approach axis through the
    grasp centre), in ``directions`` directions. Each pad carries half the tangential force plus the
    couple of the torque about the axes square to the closing axis (lever: the contacts' distance), and
    half the torque about the closing axis as torsion.

    Args:
        grasp: The grasp (world frame).
        contacts: The two contacts (2, 3), m, world (from :func:`~robointel.learning.grasp.quality.grasp_quality`).
        cloud: The part's points (n, 3) for the contact patches (the completed cloud).
        part: The part's mass and centre of mass.
        gripper: The jaws (``grip_force`` per finger, pad size).
        shake: The shake (default :class:`Shake`).
        mu: Friction coefficient of the pads on the part.
        base: (x, y) of the robot base axis (m, world).
        directions: Horizontal acceleration directions tried.

    Returns:
        The :class:`Hold`.

    Raises:
        InvalidInput: contacts not (2, 3) or not finite, or ``mu`` not positive.
    """
    C = as_array(contacts, "contacts", (2, 3))
    if not (np.isfinite(mu) and mu > 0):
        raise InvalidInput(f"hold: mu must be > 0, got {mu}", value=mu)
    shake = shake or Shake()
    y = grasp.axis
    s = (C - grasp.centre) @ y
    width = float(abs(s[0] - s[1]))
    patch = min(contact_patch(cloud, grasp, float(si), gripper) for si in s)
    F = gripper.grip_force
    mu_t = 2.0 / 3.0 * mu * patch
    r = np.asarray(part.com, float) - grasp.centre
    lever = float(np.linalg.norm(r - (r @ y) * y))
    radius = float(np.linalg.norm(grasp.centre[:2] - np.asarray(base, float)))
    r_h = float(np.linalg.norm(r - (r @ grasp.approach) * grasp.approach))
    a_peak = shake.peak_acceleration(radius, shake.j1_amplitude) + shake.peak_acceleration(r_h, shake.j6_amplitude)
    worst_u, worst_tau, worst_ft = 0.0, 0.0, 0.0
    for k in range(directions):
        ang = 2 * np.pi * k / directions
        a = np.array([a_peak * np.cos(ang), a_peak * np.sin(ang), GRAVITY])
        f = part.mass * a
        tau = np.cross(r, f)
        tau_y = float(tau @ y)
        tau_perp = tau - tau_y * y
        f_t = f - (f @ y) * y
        ft_pad = 0.5 * float(np.linalg.norm(f_t)) + float(np.linalg.norm(tau_perp)) / max(width, 2e-3)
        u = float(np.hypot(ft_pad / (mu * F), 0.5 * abs(tau_y) / (mu_t * F)))
        if u > worst_u:
            worst_u, worst_tau, worst_ft = u, abs(tau_y), ft_pad
    margin = float("inf") if worst_u == 0 else 1.0 / worst_u
    return Hold(margin, lever, worst_tau, worst_ft, patch)
