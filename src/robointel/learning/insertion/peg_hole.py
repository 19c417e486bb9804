"""The peg-hole task of the insertion (Sec. 5.5): a round peg with a hemispherical tip and a chamferless hole.

The hole is built from primitive geoms (a ring of ``n_sides`` boxes whose inner faces are tangent to the
hole circle, and a bottom plate): a hole mesh would collide as its convex hull. Contacts are stiff
(1 ms step, solref time constant 2 ms, a solimp width below the radial gap, elliptic cones, zero margins).
Steel on steel: sliding friction 0.2 (lubricated) and the torsional friction of a Hertz patch,
(3 pi / 16) mu a with a ~ 0.2 mm (a 12.7 mm sphere on a flat at 100 N): :data:`STEEL_TORSIONAL`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.learning.hdd import Contact, Tool

#: tool pointing straight down in the world
R_DOWN = np.diag([1.0, -1.0, -1.0])
#: torsional friction (m) of a steel Hertz contact: (3 pi / 16) x 0.2 x 0.2 mm (MuJoCo's default 5 mm is a
#: 25 mm patch: 2 N m of spin resistance at a 400 N wedge contact)
STEEL_TORSIONAL = 2.5e-5


def _steel() -> Contact:
    return Contact(torsional=STEEL_TORSIONAL)


@dataclass(frozen=True)
class PegHole:
    """The peg-hole task. Lengths in metres; ``clearance`` is diametral (hole minus peg diameter).

    Attributes:
        peg_radius: Peg radius (m); 12.7 mm is the dissertation's 25.4 mm peg.
        clearance: Diametral clearance (m), in (0, 2 mm); 20 um is the middle of an H7/h7 fit at 25 mm.
        depth: Hole depth (m).
        top: World position of the hole's top centre (m), on a pedestal on the table.
        n_sides: Boxes in the ring forming the hole wall.
        wall: Wall thickness (m).
        peg_length: Peg length (m).
        contact: Stiff contact parameters of the peg and the hole.
    """

    peg_radius: float = 0.0127
    clearance: float = 20e-6
    depth: float = 0.03
    top: tuple[float, float, float] = (0.60, 0.0, 0.20)
    n_sides: int = 24
    wall: float = 0.012
    peg_length: float = 0.06
    contact: Contact = field(default_factory=_steel)

    def __post_init__(self) -> None:
        if not (0 < self.clearance < 0.002):
            raise InvalidInput(f"clearance must be in (0, 2 mm), got {self.clearance!r}", value=self.clearance)
        if self.contact.solimp[2] >= 0.5 * self.clearance:
            raise InvalidInput("the contact impedance width must be below the radial clearance", value=self.contact)

    @property
    def hole_radius(self) -> float:
        """Hole radius (m)."""
        return self.peg_radius + 0.5 * self.clearance

    @property
    def bottom_z(self) -> float:
        """World height of the hole's bottom (m)."""
        return self.top[2] - self.depth

    def tool(self, *, interference: float = 0.0) -> Tool:
        """The peg as a :class:`Tool`.

        Args:
            interference: Diametral oversize (m); > 0 makes the peg that much larger than the hole.

        Returns:
            The tool carrying the peg.
        """
        r = self.hole_radius + 0.5 * interference if interference > 0 else self.peg_radius
        return Tool(radius=r, length=self.peg_length)

    def add_hole(self, spec: mujoco.MjSpec, *, contype: int = 2, conaffinity: int = 3) -> None:
        """Add the hole (ring of boxes ``hole/wall_k``, ``hole/bottom``) and its pedestal to the world.

        Args:
            spec: The MuJoCo spec to extend.
            contype: Contact type bits of the hole's geoms.
            conaffinity: Contact affinity bits of the hole's geoms.
        """
        wb = spec.worldbody
        cx, cy, top = self.top
        R, t, n, D = self.hole_radius, self.wall, self.n_sides, self.depth
        width = 2 * (R + t) * np.tan(np.pi / n) * 1.05
        for k in range(n):
            th = 2 * np.pi * k / n
            q = np.empty(4)
            mujoco.mju_axisAngle2Quat(q, np.array([0.0, 0.0, 1.0]), th)
            g = wb.add_geom(name=f"hole/wall_{k}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[t / 2, width / 2, D / 2],
                            pos=[cx + (R + t / 2) * np.cos(th), cy + (R + t / 2) * np.sin(th), top - D / 2], quat=q,
                            rgba=[0.55, 0.6, 0.7, 1], contype=contype, conaffinity=conaffinity)
            self.contact.apply(g)
        g = wb.add_geom(name="hole/bottom", type=mujoco.mjtGeom.mjGEOM_BOX, size=[R + t, R + t, 0.005],
                        pos=[cx, cy, top - D - 0.005], rgba=[0.5, 0.55, 0.65, 1], contype=contype,
                        conaffinity=conaffinity)
        self.contact.apply(g)
        ph = top - D - 0.01
        if ph > 0:
            g = wb.add_geom(name="hole/pedestal", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.04, 0.04, ph / 2],
                            pos=[cx, cy, ph / 2], rgba=[0.4, 0.4, 0.45, 1], contype=contype,
                            conaffinity=conaffinity)
            self.contact.apply(g)

    def build(self, spec: mujoco.MjSpec) -> None:
        """Add the task's environment (the hole) to a spec.

        Args:
            spec: The MuJoCo spec to extend.
        """
        self.add_hole(spec)

    def pre_insert_pose(self, tool: Tool, height: float = 0.003) -> npt.NDArray[np.float64]:
        """Tool pose pointing down on the hole axis.

        Args:
            tool: The tool (its ``tip`` offset places the pose).
            height: Height of the tip above the hole's top (m).

        Returns:
            The (4, 4) tool pose in the world.
        """
        T = np.eye(4)
        T[:3, :3] = R_DOWN
        T[:3, 3] = np.array(self.top) + np.array([0, 0, height + tool.tip])
        return T


def wall_geom_range(model: mujoco.MjModel) -> tuple[int, int]:
    """First and last geom id of the hole wall (``hole/wall_*``), (-1, -2) when there is none.

    Args:
        model: A compiled model with the hole.

    Returns:
        The inclusive id range of the wall geoms.
    """
    ids = [g for g in range(model.ngeom) if (model.geom(g).name or "").startswith("hole/wall")]
    return (int(min(ids)), int(max(ids))) if ids else (-1, -2)


def tip_point(T: npt.NDArray[np.float64], tool: Tool) -> npt.NDArray[np.float64]:
    """World position (3,) of the tool's tip for the (4, 4) tool pose ``T`` (m)."""
    return T[:3, 3] + T[:3, 2] * tool.tip


def wall_penetration(data: mujoco.MjData, walls: tuple[int, int], peg: int) -> float:
    """Deepest penetration (m, >= 0) of the peg geom into the hole wall in the current contacts.

    Args:
        data: The simulation state (after a step).
        walls: Inclusive geom id range of the wall (:func:`wall_geom_range`).
        peg: Geom id of the peg.

    Returns:
        The penetration depth (m), 0 without wall contact.
    """
    n = data.ncon
    if n == 0:
        return 0.0
    g = data.contact.geom[:n]
    dist = data.contact.dist[:n]
    other = np.where(g[:, 0] == peg, g[:, 1], np.where(g[:, 1] == peg, g[:, 0], -1))
    m = (other >= walls[0]) & (other <= walls[1])
    return float(max(0.0, -dist[m].min())) if np.any(m) else 0.0
