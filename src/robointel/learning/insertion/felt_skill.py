"""The scripted person feeling the face and inserting with the hand-held device, and the skill learned from it.

The person (:func:`demonstrate_felt`) runs :class:`~robointel.learning.insertion.felt.FeltStrategy` with
their own speeds and reflex gains on the free device (hand impedance, tremor, sensor noise); each
demonstration records, besides the device's pose and wrench, what the person felt as state (the
remaining tilt to the felt face normal, in the tool frame) and what they commanded (the hand's twist).
:class:`FeltSkill` learns the commanded rotation from the felt tilt with GMR, (5.14)-(5.17), and the
strategy's speeds and forces as the demonstrations' medians; its :meth:`FeltSkill.policy` is the robot's
insertion policy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput
from robointel.geometry.rotations import rotation_about, so3_exp, so3_log
from robointel.learning.demonstration import Demonstration
from robointel.learning.gmr import GaussianMixtureRegression, held_out_r2
from robointel.learning.insertion.demonstrator import PHASES, Demonstrator
from robointel.learning.insertion.felt import AXIAL_DAMPING, STAGES, FeltStrategy, RotationModel
from robointel.learning.insertion.hdd_scene import HDDScene
from robointel.learning.insertion.peg_hole import R_DOWN, PegHole, tip_point

#: the strategy's stage -> the demonstration phase label (feeling is approach, turning square is rotation)
STAGE_PHASE = {"aside": 0, "touch": 0, "feel": 0, "cross": 0, "lift": 1, "align": 1, "return": 2, "insert": 2}
#: strategy parameters each person draws (uniform bounds) and the skill takes as the demonstrations' median
PERSON_RANGES = {"aside": (0.0183, 0.0191), "circle_radius": (0.0014, 0.0016), "circle_hz": (0.6, 0.9),
                 "feel_push": (0.0012, 0.0018), "k_align": (2.5, 3.5), "w_max": (0.06, 0.10),
                 "v_insert": (0.008, 0.012)}


def strategy_with(centre: float, params: dict[str, float], rotation_model: RotationModel | None = None) -> FeltStrategy:
    """A :class:`FeltStrategy` with the :data:`PERSON_RANGES` parameters in ``params`` (others default).

    Args:
        centre: Distance (m) from the F/T sensor to the ball tip's centre.
        params: Values of (some of) the :data:`PERSON_RANGES` keys.
        rotation_model: The learned rotation (None: the reflex).

    Returns:
        The strategy.
    """
    d = FeltStrategy(centre=centre)
    g = {k: float(params.get(k, getattr(d, k))) for k in PERSON_RANGES}
    return FeltStrategy(centre=centre, aside=g["aside"], circle_radius=g["circle_radius"], circle_hz=g["circle_hz"],
                        feel_push=g["feel_push"], k_align=g["k_align"], w_max=g["w_max"], v_insert=g["v_insert"],
                        rotation_model=rotation_model)


def demonstrate_felt(task: PegHole, rng: np.random.Generator, *, scene: HDDScene | None = None,
                     person: Demonstrator | None = None, name: str = "", time_limit: float = 20.0,
                     completion: float = 0.3) -> Demonstration:
    """One demonstration of the feel-align-insert strategy by the scripted person with the device.

    The device starts with its tip 3 mm above the hole's face, up to ``person.max_lateral`` off the axis
    and tilted up to ``person.max_tilt_deg`` (uniform, random direction). The hand (``person``'s firm grip:
    ``stiffness``, ``damping``, ``rot_stiffness``) follows a reference moved by the strategy's twist; the
    axial reference leads the device by at most the push the strategy asks for (``AXIAL_DAMPING`` x speed).

    Args:
        task: The peg-hole task.
        rng: Generator of the person's variation, the start error, tremor and sensor noise.
        scene: The device scene (built from ``task`` when None).
        person: The hand's impedance and noise (default :class:`Demonstrator`).
        name: Name of the demonstration.
        time_limit: Longest demonstration (s).
        completion: Hold after seating (s), labelled ``completion``.

    Returns:
        The demonstration at 100 Hz; ``labels`` map the stages to :data:`PHASES` (:data:`STAGE_PHASE`);
        ``meta`` holds ``tilt_error`` (n, 2) rad, ``command`` (n, 5) m/s and rad/s, ``stage`` (n,) indices
        into :data:`STAGES`, the drawn ``params``, ``seated``, ``normal_error_rad`` and the start errors.
    """
    scene = scene or HDDScene(task)
    person = person or Demonstrator()
    tool = scene.tool
    dt = float(scene.model.opt.timestep)
    params = {k: float(rng.uniform(*b)) for k, b in PERSON_RANGES.items()}
    strat = strategy_with(tool.tip - tool.radius, params)
    tilt = np.radians(rng.uniform(0.0, person.max_tilt_deg))
    phi = rng.uniform(0, 2 * np.pi)
    R = rotation_about(np.array([np.cos(phi), np.sin(phi), 0.0]), tilt) @ R_DOWN
    lat = rng.uniform(-person.max_lateral, person.max_lateral, 2)
    tip = np.array(task.top) + np.array([lat[0], lat[1], 0.003])
    T0 = np.eye(4)
    T0[:3, :3], T0[:3, 3] = R, tip - R[:, 2] * tool.tip
    scene.reset(T0)
    cd = strat.centre
    c_ref, R_ref = T0[:3, 3] + R[:, 2] * cd, R.copy()
    mg = np.array([0.0, 0.0, scene.mass * 9.81])
    tremor_f, tremor_a = rng.uniform(8, 12, 3), rng.uniform(0.2e-4, 0.6e-4, 3)
    tremor_ph = rng.uniform(0, 2 * np.pi, (3, 3))
    every = max(1, int(round(strat.dt / dt)))
    ts, poses, wrenches, labels, errs, cmds, stages = [], [], [], [], [], [], []
    tw = np.zeros(5)
    seated_at = None
    n_steps = int(time_limit / dt)
    for k in range(n_steps):
        t = k * dt
        T = scene.pose()
        if k % every == 0:
            w = scene.wrench()
            w[:3] += person.force_noise * rng.standard_normal(3)
            w[3:] += person.torque_noise * rng.standard_normal(3)
            phase = 3 if seated_at is not None else STAGE_PHASE[strat.stage]
            if seated_at is None:
                tw = strat(w, np.asarray(np.linalg.solve(T0, T), float))
            else:
                tw = np.zeros(5)
            ts.append(t)
            poses.append(T)
            wrenches.append(w)
            labels.append(phase)
            errs.append(strat.tilt_error.copy())
            cmds.append(tw.copy())
            stages.append(STAGES.index(strat.stage))
        # the hand's reference: the ball centre and the orientation, moved by the commanded twist
        c_ref = c_ref + R_ref @ np.array([tw[0], tw[1], tw[2]]) * dt
        R_ref = so3_exp(R_ref @ np.array([tw[3], tw[4], 0.0]) * dt) @ R_ref
        c = T[:3, 3] + T[:3, 2] * cd
        z = R_ref[:, 2]
        lead = float(z @ (c_ref - c))
        cap = max(AXIAL_DAMPING * tw[2], 0.5) / person.stiffness
        if lead > cap:
            c_ref = c_ref - z * (lead - cap)
        trem = tremor_a @ np.sin(2 * np.pi * tremor_f[:, None] * t + tremor_ph)
        p_ref = c_ref - z * cd + trem
        v, om = scene.twist()
        f = person.stiffness * (p_ref - T[:3, 3]) - person.damping * v + mg
        tq = person.rot_stiffness * so3_log(R_ref @ T[:3, :3].T) - person.rot_damping * om
        scene.step(f, tq)
        if seated_at is None and tip_point(scene.pose(), tool)[2] - task.bottom_z < 1e-3:
            seated_at = t
        if seated_at is not None and t - seated_at > completion:
            break
    n_true = T0[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    nerr = float(np.arccos(np.clip(n_true @ strat.normal, -1, 1))) if strat.normal is not None else float("nan")
    meta = {"seated": seated_at is not None, "tilt_error": np.array(errs), "command": np.array(cmds),
            "stage": np.array(stages), "params": params, "normal_error_rad": nerr, "residual_tilt": float(tilt),
            "lateral_error": lat.tolist(), "strategy": "felt"}
    return Demonstration.create(np.array(ts), np.array(poses), np.array(wrenches), np.array(labels),
                                action_names=PHASES, device="hdd", name=name, meta=meta)


class FeltSkill:
    """The rotation the person commanded for the tilt they felt, learned with GMR; speeds as their medians.

    Inputs: the remaining tilt (2,) to the felt face normal in the tool frame (rad); outputs the commanded
    rotation rate [wx, wy] (rad/s), from the samples of the stages after feeling (lift, align, return,
    insert). ``r2_`` is each output's coefficient of determination on held-out demonstrations (folds over
    demonstrations).
    """

    def __init__(self, n_components: int = 5, *, random_state: int = 0, cv_folds: int = 3) -> None:
        """Set up an unfitted skill.

        Args:
            n_components: Gaussian components of the mixture.
            random_state: Seed of the EM initialisation.
            cv_folds: Folds (over demonstrations) of the held-out check.
        """
        self.gmr = GaussianMixtureRegression(n_components, random_state=random_state)
        self.cv_folds = int(cv_folds)
        self.random_state = int(random_state)

    @staticmethod
    def _samples(demos: Sequence[Demonstration]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                                                           npt.NDArray[np.int_]]:
        xs, ys, gs = [], [], []
        first = STAGES.index("lift")
        for i, d in enumerate(demos):
            if d.meta.get("strategy") != "felt":
                raise InvalidInput(f"demonstration {i} is not a felt-strategy demonstration", value=d.name)
            m = np.asarray(d.meta["stage"]) >= first
            m &= np.asarray(d.labels) < PHASES.index("completion")
            xs.append(np.asarray(d.meta["tilt_error"])[m])
            ys.append(np.asarray(d.meta["command"])[m][:, 3:5])
            gs.append(np.full(int(m.sum()), i))
        return np.concatenate(xs), np.concatenate(ys), np.concatenate(gs)

    def fit(self, demos: Sequence[Demonstration]) -> FeltSkill:
        """Fit on felt-strategy demonstrations (:func:`demonstrate_felt`).

        Args:
            demos: The demonstrations (seated or not: the rotation is learned from what was felt and done).

        Returns:
            This skill, fitted.

        Raises:
            InvalidInput: no demonstrations, one that is not a felt-strategy demonstration, or no samples.
        """
        if len(demos) == 0:
            raise InvalidInput("FeltSkill.fit needs at least one demonstration", value=0)
        X, Y, G = self._samples(demos)
        if len(X) < 10:
            raise InvalidInput(f"FeltSkill.fit: only {len(X)} samples after feeling", value=len(X))
        self.x_mean_, self.x_scale_ = X.mean(0), X.std(0) + 1e-12
        self.y_mean_, self.y_scale_ = Y.mean(0), Y.std(0) + 1e-12
        self.x_lo_, self.x_hi_ = X.min(0), X.max(0)
        self.y_lo_, self.y_hi_ = Y.min(0), Y.max(0)
        self.gmr.fit((X - self.x_mean_) / self.x_scale_, (Y - self.y_mean_) / self.y_scale_)
        self.params_ = {k: float(np.median([d.meta["params"][k] for d in demos])) for k in PERSON_RANGES}
        self.r2_ = held_out_r2(X, Y, G, n_components=self.gmr.n_components, folds=self.cv_folds,
                               random_state=self.random_state, x_eps=1e-12, sst_about="test",
                               single_group=np.nan, constant_output=None)
        self.n_demos_ = len(demos)
        self.n_samples_ = len(X)
        return self

    def predict(self, tilt_error: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Commanded rotation rate [wx, wy] (rad/s) for remaining tilts (2,) or (n, 2) (rad), no extrapolation.

        Args:
            tilt_error: (2,) or (n, 2) remaining tilt in the tool frame (rad).

        Returns:
            (2,) or (n, 2) rotation rates, within the demonstrated range.
        """
        x = np.asarray(tilt_error, float)
        one = x.ndim == 1
        x = np.clip(np.atleast_2d(x), self.x_lo_, self.x_hi_)
        y = self.gmr.predict((x - self.x_mean_) / self.x_scale_) * self.y_scale_ + self.y_mean_
        y = np.clip(y, self.y_lo_, self.y_hi_)
        return y[0] if one else y

    def policy(self, centre: float) -> FeltStrategy:
        """The robot's insertion policy: the strategy with the demonstrations' parameters and the learned rotation.

        Args:
            centre: Distance (m) from the F/T sensor to the ball tip's centre on the robot's tool.

        Returns:
            A fresh :class:`FeltStrategy` (proprioceptive policy for :meth:`RobotCell.insert`).
        """
        p = {k: v for k, v in self.params_.items() if k not in ("k_align", "w_max")}
        return strategy_with(centre, p, self.predict)
