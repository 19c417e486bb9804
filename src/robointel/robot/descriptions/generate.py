"""Generate the built-in robot descriptions (URDF) shipped with robointel.

Run ``python -m robointel.robot.descriptions.generate`` to rewrite the ``.urdf`` files beside this
module. The files are committed; this script documents where every number comes from.

FANUC LR Mate 200iD/7L
    Kinematics and limits are the public numbers (also in ROS-Industrial's
    ``fanuc_lrmate200id_support``): joint offsets J1 z 0.330, J2 x 0.050, J3 z 0.440, J4 z 0.035,
    J5 x 0.420, flange x 0.080 (m); axes z, y, -y, -x, -y, -x; limits and maximum speeds from the
    data sheet. Collision geometry is ours: boxes and cylinders that envelope the arm.

    **Masses and inertias are estimates.** The manufacturer publishes only the total mass (27 kg)
    and the payload (7 kg). We give every link a uniform density so that the volumes of its
    collision primitives add up to the published total (mass proportional to primitive volume) and
    compute each link's centre of mass and inertia tensor from those primitives (parallel-axis
    theorem). Torque limits are estimates as well (the data sheet gives wrist moments of 16.6, 16.6
    and 9.4 N m; the main axes are sized to lift the payload at full reach with margin). Viscous and
    Coulomb friction are plausible estimates for harmonic-drive/RV reducers.

SCARA (``scara2``)
    A two-link planar arm for the dynamic imitation study (Ch. 3.2): two revolute joints about z,
    link lengths 0.40 m and 0.35 m, masses 4.0 kg and 2.5 kg as uniform boxes.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Prim:
    """A collision primitive in its link frame.

    ``kind`` is "box" (size = full extents) or "cylinder" (size = (radius, length)), ``axis`` the cylinder axis
    ("x", "y" or "z").
    """

    kind: str
    size: tuple[float, ...]
    center: tuple[float, float, float]
    axis: str = "z"

    def volume(self) -> float:
        """Volume of the primitive, m^3."""
        if self.kind == "box":
            return float(np.prod(self.size))
        r, h = self.size
        return float(np.pi * r * r * h)

    def inertia_about_center(self, mass: float) -> np.ndarray:
        """Inertia tensor (kg m^2) of the uniform solid about its own centre, link-frame axes."""
        if self.kind == "box":
            a, b, c = self.size
            return mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        r, h = self.size
        i_ax = 0.5 * mass * r * r
        i_tr = mass * (3 * r * r + h * h) / 12.0
        d = {"x": [i_ax, i_tr, i_tr], "y": [i_tr, i_ax, i_tr], "z": [i_tr, i_tr, i_ax]}[self.axis]
        return np.diag(d)

    def urdf(self) -> str:
        """The primitive as URDF ``<origin>`` + ``<geometry>`` elements."""
        rpy = {"x": "0 1.5707963267948966 0", "y": "1.5707963267948966 0 0", "z": "0 0 0"}[self.axis]
        c = " ".join(f"{v:.6g}" for v in self.center)
        if self.kind == "box":
            geom = '<box size="{}"/>'.format(" ".join(f"{v:.6g}" for v in self.size))
            rpy = "0 0 0"
        else:
            geom = f'<cylinder radius="{self.size[0]:.6g}" length="{self.size[1]:.6g}"/>'
        return (f'    <collision>\n      <origin xyz="{c}" rpy="{rpy}"/>\n'
                f"      <geometry>{geom}</geometry>\n    </collision>\n"
                f'    <visual>\n      <origin xyz="{c}" rpy="{rpy}"/>\n'
                f"      <geometry>{geom}</geometry>\n    </visual>\n")


def link_inertial(prims: list[Prim], mass: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass (3,) and inertia about it (3, 3) of a link of uniform density."""
    vols = np.array([p.volume() for p in prims])
    masses = mass * vols / vols.sum()
    centers = np.array([p.center for p in prims], dtype=float)
    com = (masses[:, None] * centers).sum(0) / mass
    inertia = np.zeros((3, 3))
    for p, m, c in zip(prims, masses, centers):
        d = c - com
        inertia += p.inertia_about_center(m) + m * (d @ d * np.eye(3) - np.outer(d, d))
    return com, inertia


def _inertial_xml(mass: float, com: np.ndarray, inertia: np.ndarray) -> str:
    i = inertia
    return ("    <inertial>\n"
            f'      <origin xyz="{com[0]:.9g} {com[1]:.9g} {com[2]:.9g}" rpy="0 0 0"/>\n'
            f'      <mass value="{mass:.9g}"/>\n'
            f'      <inertia ixx="{i[0, 0]:.9g}" ixy="{i[0, 1]:.9g}" ixz="{i[0, 2]:.9g}" '
            f'iyy="{i[1, 1]:.9g}" iyz="{i[1, 2]:.9g}" izz="{i[2, 2]:.9g}"/>\n'
            "    </inertial>\n")


LRMATE_TOTAL_MASS = 27.0
LRMATE_LINKS: dict[str, list[Prim]] = {
    "base_link": [Prim("cylinder", (0.10, 0.20), (0.0, 0.0, 0.10), "z"),
                  Prim("box", (0.26, 0.26, 0.02), (0.0, 0.0, 0.01))],
    "link_1": [Prim("cylinder", (0.085, 0.14), (0.0, 0.0, -0.06), "z"),
               Prim("cylinder", (0.075, 0.20), (0.05, 0.0, 0.0), "y")],
    "link_2": [Prim("cylinder", (0.055, 0.30), (0.0, 0.0, 0.19), "z")],
    "link_3": [Prim("cylinder", (0.065, 0.17), (0.0, 0.0, 0.0), "y"),
               Prim("box", (0.12, 0.10, 0.10), (0.0, 0.0, 0.04))],
    "link_4": [Prim("cylinder", (0.045, 0.35), (0.165, 0.0, 0.0), "x")],
    "link_5": [Prim("cylinder", (0.038, 0.09), (0.0, 0.0, 0.0), "y"),
               Prim("cylinder", (0.032, 0.05), (0.045, 0.0, 0.0), "x")],
    "link_6": [Prim("cylinder", (0.031, 0.012), (-0.006, 0.0, 0.0), "x")],
}
#            name       parent      child    xyz                 axis         lower upper  vmax  effort damping friction
LRMATE_JOINTS = [
    ("joint_1", "base_link", "link_1", (0, 0, 0.330), (0, 0, 1), -170, 170, 370, 150.0, 1.2, 2.0),
    ("joint_2", "link_1", "link_2", (0.050, 0, 0), (0, 1, 0), -100, 145, 310, 150.0, 1.2, 2.0),
    ("joint_3", "link_2", "link_3", (0, 0, 0.440), (0, -1, 0), -70, 213, 410, 80.0, 0.8, 1.5),
    ("joint_4", "link_3", "link_4", (0, 0, 0.035), (-1, 0, 0), -190, 190, 550, 16.6, 0.2, 0.4),
    ("joint_5", "link_4", "link_5", (0.420, 0, 0), (0, -1, 0), -125, 125, 545, 16.6, 0.2, 0.4),
    ("joint_6", "link_5", "link_6", (0.080, 0, 0), (-1, 0, 0), -360, 360, 1000, 9.4, 0.1, 0.2),
]


def lrmate_urdf() -> str:
    """URDF of the FANUC LR Mate 200iD/7L from its public kinematic numbers."""
    vols = {n: sum(p.volume() for p in ps) for n, ps in LRMATE_LINKS.items()}
    total = sum(vols.values())
    out = ['<?xml version="1.0"?>\n',
           "<!-- FANUC LR Mate 200iD/7L, generated by robointel.robot.descriptions.generate.\n"
           "     Kinematics and limits: public data. Masses/inertias/torque limits/friction: ESTIMATES\n"
           "     (uniform density over our primitive collision geometry, 27 kg total). -->\n",
           '<robot name="lrmate200id7l">\n']
    for name, prims in LRMATE_LINKS.items():
        mass = LRMATE_TOTAL_MASS * vols[name] / total
        com, inertia = link_inertial(prims, mass)
        out.append(f'  <link name="{name}">\n')
        out.append(_inertial_xml(mass, com, inertia))
        out.extend(p.urdf() for p in prims)
        out.append("  </link>\n")
    for n, par, ch, xyz, ax, lo, up, vmax, eff, damp, fric in LRMATE_JOINTS:
        out.append(
            f'  <joint name="{n}" type="revolute">\n'
            f'    <origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="0 0 0"/>\n'
            f'    <parent link="{par}"/>\n    <child link="{ch}"/>\n'
            f'    <axis xyz="{ax[0]} {ax[1]} {ax[2]}"/>\n'
            f'    <limit effort="{eff}" lower="{np.radians(lo):.17g}" upper="{np.radians(up):.17g}" '
            f'velocity="{np.radians(vmax):.17g}"/>\n'
            f'    <dynamics damping="{damp}" friction="{fric}"/>\n'
            "  </joint>\n")
    out.append(
        '  <link name="base"/>\n'
        '  <joint name="base_link-base" type="fixed">\n    <origin xyz="0 0 0.330" rpy="0 0 0"/>\n'
        '    <parent link="base_link"/>\n    <child link="base"/>\n  </joint>\n'
        '  <link name="flange"/>\n'
        '  <joint name="link_6-flange" type="fixed">\n    <origin xyz="0 0 0" rpy="0 0 0"/>\n'
        '    <parent link="link_6"/>\n    <child link="flange"/>\n  </joint>\n'
        '  <link name="tool0"/>\n'
        '  <joint name="flange-tool0" type="fixed">\n'
        '    <origin xyz="0 0 0" rpy="3.141592653589793 -1.5707963267948966 0"/>\n'
        '    <parent link="flange"/>\n    <child link="tool0"/>\n  </joint>\n')
    out.append("</robot>\n")
    return "".join(out)


SCARA_L1, SCARA_L2 = 0.40, 0.35


def scara_urdf() -> str:
    """URDF of the 2-link SCARA of the dynamic imitation study."""
    links = {
        "base_link": ([Prim("cylinder", (0.08, 0.30), (0.0, 0.0, 0.15), "z")], 8.0),
        "link_1": ([Prim("box", (SCARA_L1, 0.08, 0.06), (SCARA_L1 / 2, 0.0, 0.0))], 4.0),
        "link_2": ([Prim("box", (SCARA_L2, 0.06, 0.05), (SCARA_L2 / 2, 0.0, 0.0))], 2.5),
    }
    out = ['<?xml version="1.0"?>\n',
           "<!-- Two-link planar SCARA, generated by robointel.robot.descriptions.generate. -->\n",
           '<robot name="scara2">\n']
    for name, (prims, mass) in links.items():
        com, inertia = link_inertial(prims, mass)
        out.append(f'  <link name="{name}">\n')
        out.append(_inertial_xml(mass, com, inertia))
        out.extend(p.urdf() for p in prims)
        out.append("  </link>\n")
    joints = [("joint_1", "base_link", "link_1", (0, 0, 0.33), 60.0),
              ("joint_2", "link_1", "link_2", (SCARA_L1, 0, 0), 30.0)]
    for n, par, ch, xyz, eff in joints:
        out.append(
            f'  <joint name="{n}" type="revolute">\n'
            f'    <origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="0 0 0"/>\n'
            f'    <parent link="{par}"/>\n    <child link="{ch}"/>\n    <axis xyz="0 0 1"/>\n'
            f'    <limit effort="{eff}" lower="{np.radians(-170):.17g}" upper="{np.radians(170):.17g}" '
            f'velocity="{np.radians(360):.17g}"/>\n'
            '    <dynamics damping="0.05" friction="0.0"/>\n  </joint>\n')
    out.append(
        '  <link name="flange"/>\n'
        '  <joint name="link_2-flange" type="fixed">\n'
        f'    <origin xyz="{SCARA_L2} 0 0" rpy="0 0 0"/>\n'
        '    <parent link="link_2"/>\n    <child link="flange"/>\n  </joint>\n')
    out.append("</robot>\n")
    return "".join(out)


def main() -> None:
    """Write the built-in URDF files next to this script."""
    (HERE / "lrmate200id7l.urdf").write_text(lrmate_urdf())
    (HERE / "scara2.urdf").write_text(scara_urdf())


if __name__ == "__main__":
    main()
