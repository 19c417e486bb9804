"""Rigid-body dynamics (2.5) of a robot model on Pinocchio, with viscous and Coulomb friction.

A mixin of :class:`robointel.robot.Robot`: it reads the robot's Pinocchio ``model``/``data``, its
friction coefficients and its configuration check.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike


class RigidBodyDynamics:
    """M(q), C(q, qd) qd, G(q), friction, RNEA and ABA for the robot that mixes this in."""

    model: Any
    data: Any
    viscous: np.ndarray
    coulomb: np.ndarray

    def check_q(self, q: ArrayLike, name: str = "q", *, limits: bool = False) -> np.ndarray:  # pragma: no cover
        """A validated configuration (the robot's)."""
        raise NotImplementedError

    def mass_matrix(self, q: ArrayLike) -> np.ndarray:
        """M(q), n x n."""
        q = self.check_q(q)
        M = pin.crba(self.model, self.data, q)
        return np.triu(M) + np.triu(M, 1).T

    def nonlinear_effects(self, q: ArrayLike, qd: ArrayLike) -> np.ndarray:
        """C(q, qd) qd + G(q)."""
        return pin.nonLinearEffects(self.model, self.data, self.check_q(q), self.check_q(qd, "qd"))

    def coriolis(self, q: ArrayLike, qd: ArrayLike) -> np.ndarray:
        """C(q, qd) qd (Coriolis and centrifugal torques)."""
        return self.nonlinear_effects(q, qd) - self.gravity(q)

    def gravity(self, q: ArrayLike) -> np.ndarray:
        """G(q)."""
        return pin.computeGeneralizedGravity(self.model, self.data, self.check_q(q))

    def friction(self, qd: ArrayLike, *, smooth: float = 1e-3) -> np.ndarray:
        """Joint friction torques F_v qd + F_c sign(qd) (tanh-smoothed over ``smooth`` rad/s)."""
        qd = self.check_q(qd, "qd")
        return self.viscous * qd + self.coulomb * np.tanh(qd / smooth)

    def inverse_dynamics(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, *, friction: bool = False) -> np.ndarray:
        """Tau = M qdd + C qd + G (+ friction) by RNEA."""
        tau = pin.rnea(self.model, self.data, self.check_q(q), self.check_q(qd, "qd"), self.check_q(qdd, "qdd"))
        return tau + self.friction(qd) if friction else tau

    def forward_dynamics(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike, *, friction: bool = False) -> np.ndarray:
        """Qdd = M^-1 (tau - C qd - G (- friction)) by ABA."""
        q, qd, tau = self.check_q(q), self.check_q(qd, "qd"), self.check_q(tau, "tau")
        if friction:
            tau = tau - self.friction(qd)
        return pin.aba(self.model, self.data, q, qd, tau)
