"""The flange F/T sensor of the workcell (readings with bias and noise) and external wrenches (a hand)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robointel._validate import as_array
from robointel.errors import InvalidInput
from robointel.sim.mjcf import TOOL_BODY
from robointel.sim.workcell_model import WorkcellModel


@dataclass
class FTSensor:
    """Configuration of the simulated F/T sensor's imperfections (added in Python).

    Args:
        bias: (6,) constant offset [N, N, N, N m, N m, N m] added to every reading.
        noise_std: scalar or (6,) standard deviation of white Gaussian noise.
        seed: seed of the noise generator (deterministic by default).
    """

    bias: Any = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    noise_std: Any = 0.0
    seed: int | None = 0

    def __post_init__(self) -> None:
        self.bias = as_array(self.bias, "FTSensor.bias", (6,))
        self.noise_std = np.broadcast_to(as_array(self.noise_std, "FTSensor.noise_std"), (6,)).astype(float)
        if np.any(self.noise_std < 0):
            raise InvalidInput("FTSensor.noise_std must be >= 0", value=self.noise_std)
        self.rng = np.random.default_rng(self.seed)


class FTSensing(WorkcellModel):
    """Read the F/T sensor; apply and clear an external wrench."""

    def ft_reading(self, noise: float | npt.ArrayLike | None = None, bias: npt.ArrayLike | None = None, *,
                   frame: str = "sensor") -> np.ndarray:
        """The F/T wrench [f (N); m (N m)] exerted by the tool on the sensor, (6,).

        ``frame="sensor"`` (the flange frame) or ``"world"`` (same wrench, axes of the world
        frame, torque still about the sensor origin). ``noise`` (std, scalar or (6,)) and ``bias``
        (6,) override the :class:`FTSensor` configuration for this reading. The value is the one
        computed in the last physics step.
        """
        if not self._has_ft:
            raise InvalidInput("this workcell has no F/T sensor; build it with ft_sensor=True")
        w = -self.data.sensordata[self._ft_adr:self._ft_adr + 6].copy()
        cfg = self.ft_config
        b = cfg.bias if bias is None else as_array(bias, "bias", (6,))
        s = cfg.noise_std if noise is None else np.broadcast_to(as_array(noise, "noise"), (6,))
        w = w + b
        if np.any(s > 0):
            w = w + s * cfg.rng.standard_normal(6)
        if frame == "world":
            R = self.data.site_xmat[self._site_id].reshape(3, 3)
            return np.concatenate([R @ w[:3], R @ w[3:]])
        if frame != "sensor":
            raise InvalidInput(f"frame must be 'sensor' or 'world', got {frame!r}", value=frame)
        return w

    def sensor_pose(self) -> np.ndarray:
        """4x4 world pose of the F/T sensor frame."""
        if not self._has_ft:
            raise InvalidInput("this workcell has no F/T sensor")
        T = np.eye(4)
        T[:3, :3] = self.data.site_xmat[self._site_id].reshape(3, 3)
        T[:3, 3] = self.data.site_xpos[self._site_id]
        return T

    def apply_wrench(self, force: npt.ArrayLike, torque: npt.ArrayLike = (0.0, 0.0, 0.0),
                     point: npt.ArrayLike | None = None, body: str | None = None) -> None:
        """Apply a persistent external wrench (the human's hand) until :meth:`clear_wrench`.

        Args:
            force: (3,) N, world frame.
            torque: (3,) N m, world frame (a pure couple).
            point: (3,) world point where the force acts at the time of the call; it then moves
                with the body. Default: the body frame origin.
            body: MuJoCo body name; default the tool after the F/T sensor (so the sensor feels the
                wrench; use ``"link_6"`` to push the flange link before the sensor).
        """
        f = as_array(force, "force", (3,))
        tq = as_array(torque, "torque", (3,))
        name = TOOL_BODY if body is None else body
        bid = self._body_id(name)
        d = self.data
        R = d.xmat[bid].reshape(3, 3)
        p = d.xpos[bid].copy() if point is None else as_array(point, "point", (3,))
        self._wrench = (bid, f.copy(), tq.copy(), R.T @ (p - d.xpos[bid]))
        self._apply_wrench_now()

    def clear_wrench(self) -> None:
        """Remove the external wrench."""
        self._wrench = None
        self.data.xfrc_applied[:] = 0

    def _apply_wrench_now(self) -> None:
        bid, f, tq, p_local = self._wrench
        d = self.data
        p = d.xmat[bid].reshape(3, 3) @ p_local + d.xpos[bid]
        d.xfrc_applied[bid, :3] = f
        d.xfrc_applied[bid, 3:] = tq + np.cross(p - d.xipos[bid], f)
