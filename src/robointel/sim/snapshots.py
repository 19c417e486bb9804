"""Snapshots of the whole workcell state, to roll out alternatives from one state."""
from __future__ import annotations

import mujoco

from robointel.errors import InvalidInput
from robointel.sim.workcell_model import WorkcellModel


class Snapshots(WorkcellModel):
    """Save and restore the simulation state."""

    def snapshot(self) -> dict:
        """The full simulation state for :meth:`restore` (e.g. to roll out alternatives from one state).

        MuJoCo state, controller integral, hold reference, applied wrench and grasps.
        """
        s = self._save_state()
        s["act"] = self.data.act.copy()
        s["qacc_warmstart"] = self.data.qacc_warmstart.copy()
        c = self.controller
        s["controller"] = (c.integral.copy(), c.saturated.copy(), c.last_tau.copy())
        s["hold"] = tuple(x.copy() for x in self._hold)
        s["wrench"] = None if self._wrench is None else (self._wrench[0],) + tuple(x.copy() for x in self._wrench[1:])
        s["nbody"] = self.model.nbody
        return s

    def restore(self, snapshot: dict) -> None:
        """Return to a :meth:`snapshot` of this workcell (same scene).

        Raises:
            InvalidInput: the snapshot is from another scene.
        """
        if not isinstance(snapshot, dict) or snapshot.get("nbody") != self.model.nbody \
                or snapshot["qpos"].shape != self.data.qpos.shape:
            raise InvalidInput("the snapshot does not belong to this workcell's scene", value=None)
        self._restore_state(snapshot)
        self.data.act[:] = snapshot["act"]
        self.data.qacc_warmstart[:] = snapshot["qacc_warmstart"]
        c = self.controller
        c.integral[:], c.saturated[:], c.last_tau = (snapshot["controller"][0], snapshot["controller"][1],
                                                     snapshot["controller"][2].copy())
        self._hold = tuple(x.copy() for x in snapshot["hold"])
        self._wrench = snapshot["wrench"]
        self.data.xfrc_applied[:] = 0
        if self._wrench is not None:
            self._apply_wrench_now()

    def _save_state(self) -> dict:
        d = self.data
        return {"qpos": d.qpos.copy(), "qvel": d.qvel.copy(), "time": d.time, "mocap_pos": d.mocap_pos.copy(),
                "mocap_quat": d.mocap_quat.copy(), "ctrl": d.ctrl.copy(), "eq_active": d.eq_active.copy(),
                "eq_data": self.model.eq_data.copy()}

    def _restore_state(self, s: dict) -> None:
        d = self.data
        d.qpos[:] = s["qpos"]
        d.qvel[:] = s["qvel"]
        d.time = s["time"]
        k = len(s["mocap_pos"])
        d.mocap_pos[:k] = s["mocap_pos"]
        d.mocap_quat[:k] = s["mocap_quat"]
        d.ctrl[:] = s["ctrl"]
        k = len(s["eq_active"])  # objects come before nothing else with equalities: same order
        d.eq_active[:k] = s["eq_active"]
        self.model.eq_data[:k] = s["eq_data"]
        mujoco.mj_forward(self.model, d)
        self._warn0 = self._bad_count()
