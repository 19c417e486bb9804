"""Run a trajectory on ``--robot sim|sim?process=1|fanuc://HOST`` with an optional ``--record run.mcap`` (shared)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from robointel.interface import ExecutionResult, RobotState, open_robot
from robointel.interface.open import parse_robot_url
from robointel.io.mcap_log import McapRecorder
from robointel.robot import Robot
from robointel.teach.guidance import GuidanceConfig
from robointel.teach.lead_through import lead_through
from robointel.trajectory import Trajectory


def run_on_robot(trajectory: Trajectory, url: str, record: Path | None, console: Console, *,
                 sim_kwargs: dict[str, Any] | None = None, approach: bool = True) -> ExecutionResult:
    """Execute ``trajectory`` on the robot at ``url`` with a progress bar, recording to ``record``.

    Args:
        trajectory: the trajectory (rad); the simulation is reset at its start (``sim``), a real
            robot is first brought there (``approach``).
        url: ``"sim"``, ``"sim?process=1"`` or ``"fanuc://HOST[:RMI_PORT][?sm_port=N]"``
            (:func:`~robointel.interface.open.parse_robot_url`).
        record: ``.mcap`` file to record the run to, or None.
        console: rich console for the progress bar and the summary.
        sim_kwargs: extra arguments of :class:`~robointel.interface.sim.SimRobot` (e.g. a workcell); the
            streaming process's sim (``sim?process=1``) steps the default cell and takes none of them.
        approach: a robot away from the start moves there first (a quintic joint move at 20 % of its
            limits, :meth:`~robointel.interface.Backend.move_to`); False: such a trajectory is refused.

    Returns:
        The :class:`~robointel.interface.ExecutionResult`.

    Raises:
        RobointelError: refused trajectory, controller fault, lost connection, bad URL or path.
    """
    rec = McapRecorder(record, list(trajectory.joint_names)) if record is not None else None
    u = parse_robot_url(url)
    kw: dict[str, Any] = {}
    if u.kind == "sim":
        kw = {"q0": trajectory.q[0]} if u.stream_process else dict(sim_kwargs or {}, q0=trajectory.q[0])
    try:
        with open_robot(url, recorder=rec, **kw) as robot:
            st = robot.state()
            here = st.q_cmd if st.q_cmd is not None else st.q
            gap = float(np.max(np.abs(here - trajectory.q[0])))
            if approach and gap > 1e-6:
                with console.status(f"moving to the trajectory's start ({np.degrees(gap):.1f} deg away)"):
                    move = robot.move_to(trajectory.q[0])
                console.print(f"at the start after {len(move.q_cmd) * robot.period:.1f} s")
            cycles = int(np.ceil(trajectory.duration / robot.period)) + 1
            with Progress(TextColumn("executing on " + url.split("?")[0]), BarColumn(), TimeRemainingColumn(),
                          console=console) as bar:
                task = bar.add_task("run", total=cycles)

                def tick(k: int, state: RobotState) -> None:
                    bar.update(task, completed=min(k + 1, cycles))

                res = robot.execute(trajectory, on_cycle=tick)
    finally:
        if rec is not None:
            rec.close()
    console.print(f"{url.split('?')[0]}: {len(res.q_cmd)} cycles of {robot.period * 1e3:.0f} ms, RMS measured - "
                  f"commanded {np.degrees(res.tracking_rms_rad):.4f} deg, missed cycles {res.missed_cycles}, "
                  f"compute per cycle median {np.median(res.cycle_us):.0f} us"
                  + (f"; recorded to {record}" if record is not None else ""))
    return res


def guide_on_robot(url: str, record: Path | None, duration: float, method: str, console: Console, *,
                   ft: str | None = None) -> None:
    """Lead-through on the robot at ``url`` for ``duration`` s (guidance ``method``), with a progress bar.

    Args:
        url: The robot, ``sim``, ``sim?process=1`` or ``fanuc://HOST[:RMI_PORT][?sm_port=N]``.
        record: Record the run as a ROS 2 bag (.mcap) here, if given.
        duration: How long to guide, s.
        method: Guidance method (``qp``, ``equality``, ``repulsive`` or ``nullspace``).
        console: Where the progress bar and the summary are printed.
        ft: ``netft://HOST[:PORT]``: the wrist F/T sensor of a ``fanuc`` robot (None: the
            controller's own force telemetry, if any).

    Raises:
        RobointelError: no F/T wrench from the robot, a fault, a bad URL or method.
    """
    robot = Robot.load("lrmate200id7l")
    cfg = GuidanceConfig(method=method)
    rec = McapRecorder(record, list(robot.joint_names)) if record is not None else None
    try:
        with open_robot(url, recorder=rec, **({"ft_sensor": ft} if ft is not None else {})) as arm:
            cycles = int(round(duration / arm.period))
            with Progress(TextColumn("guiding " + url.split("?")[0]), BarColumn(), TimeRemainingColumn(),
                          console=console) as bar:
                task = bar.add_task("guide", total=cycles)
                res = lead_through(arm, robot, duration, config=cfg,
                                   on_cycle=lambda k, s: bar.update(task, completed=k + 1))
    finally:
        if rec is not None:
            rec.close()
    moved = float(np.linalg.norm(robot.fk(res.q[-1])[:3, 3] - robot.fk(res.q[0])[:3, 3]))
    console.print(f"guided {len(res.t)} cycles: TCP moved {moved * 1000:.1f} mm, held {int(res.held.sum())} cycles, "
                  f"min obstacle distance {np.min(res.distance):.3f} m")
