"""The :class:`Trajectory`: sampled pose and actuator motion of a robot (the 3PRRR's columns
name the file format, :mod:`trajectories.files`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .motion import SampledMotion

if TYPE_CHECKING:
    from ident_hw.model import ThreePRRR

    from .timing import ActuatorMap

#: Array fields of a trajectory, in file order, with the names and units of their columns in the
#: trajectory files (the 3PRRR's: six actuators, a planar pose).
COLUMNS: dict[str, list[tuple[str, str]]] = {
    "t": [("t", "s")],
    "X": [("x", "m"), ("y", "m"), ("alpha", "rad")],
    "Xd": [("xd", "m/s"), ("yd", "m/s"), ("alphad", "rad/s")],
    "Xdd": [("xdd", "m/s^2"), ("ydd", "m/s^2"), ("alphadd", "rad/s^2")],
    "Theta": [(f"theta{i}", "rad") for i in (1, 2, 3)] + [(f"zeta{i}", "m") for i in (1, 2, 3)],
    "Thetad": [(f"theta{i}d", "rad/s") for i in (1, 2, 3)] + [(f"zeta{i}d", "m/s") for i in (1, 2, 3)],
    "Thetadd": [(f"theta{i}dd", "rad/s^2") for i in (1, 2, 3)] + [(f"zeta{i}dd", "m/s^2") for i in (1, 2, 3)],
}


def actuator_map(robot: ThreePRRR) -> ActuatorMap:
    """``q, qd, qdd ->`` the actuators' motion ``Theta, Thetad, Thetadd`` for ``q = [x, y, alpha,
    zeta1..3]`` (each ``(N, 6)``)."""

    def to_actuators(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> SampledMotion:
        return robot.actuated_motion(q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:])

    return to_actuators


@dataclass(frozen=True)
class Trajectory:
    """Pose and actuator motion sampled on a time grid.

    Attributes:
        name: short identifier (e.g. ``"square-2"``).
        t: ``(N,)`` strictly increasing sample times, s.
        X, Xd, Xdd: ``(N, p)`` end-effector pose and its derivatives (the 3PRRR: ``[x, y, alpha]``
            in m, m, rad; the Delta: the platform position ``[x, y, z]`` in m).
        Theta, Thetad, Thetadd: ``(N, a)`` actuator coordinates in the robot's actuator order (the
            3PRRR: ``[theta1..3 (rad), zeta1..3 (m)]``) and their derivatives.
        metadata: free-form JSON-serialisable description (generator, parameters, limits used).
    """

    name: str
    t: np.ndarray
    X: np.ndarray
    Xd: np.ndarray
    Xdd: np.ndarray
    Theta: np.ndarray
    Thetad: np.ndarray
    Thetadd: np.ndarray
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        widths: dict[str, int] = {}
        for key in COLUMNS:
            value = np.asarray(getattr(self, key), dtype=float)
            family = "Theta" if key.startswith("Theta") else key[:1]
            width = value.shape[1] if value.ndim == 2 else 0
            expected = (len(self.t),) if key == "t" else (len(self.t), widths.setdefault(family, width) or 1)
            if value.shape != expected:
                raise ValueError(f"trajectory {self.name!r}: {key} has shape {value.shape}, expected {expected}")
            if not np.all(np.isfinite(value)):
                row = int(np.argwhere(~np.isfinite(value))[0][0])
                raise ValueError(f"trajectory {self.name!r}: {key} is not finite at sample {row}")
            object.__setattr__(self, key, value)   # frozen: the validated array, once
        if len(self.t) < 2:
            raise ValueError(f"trajectory {self.name!r} needs at least 2 samples, got {len(self.t)}")
        steps = np.diff(self.t)
        if np.any(steps <= 0):
            row = int(np.argmax(steps <= 0)) + 1
            raise ValueError(f"trajectory {self.name!r}: time is not strictly increasing at sample {row}")

    @classmethod
    def from_pose(
        cls,
        robot: ThreePRRR,
        name: str,
        t: np.ndarray,
        q: np.ndarray,
        qd: np.ndarray,
        qdd: np.ndarray,
        metadata: dict | None = None,
    ) -> "Trajectory":
        """Build from the pose and carriages ``q = [x, y, alpha, zeta1..3]`` (each ``(N, 6)``).

        The revolute actuators follow analytically from the model (``robot.actuated_motion``).
        """
        actuators = actuator_map(robot)(q, qd, qdd)
        Theta, Thetad, Thetadd = actuators.q, actuators.qd, actuators.qdd
        return cls(name, t, q[:, :3], qd[:, :3], qdd[:, :3], Theta, Thetad, Thetadd, dict(metadata or {}))

    @classmethod
    def from_actuators(
        cls,
        robot: ThreePRRR,
        name: str,
        t: np.ndarray,
        Theta: np.ndarray,
        Thetad: np.ndarray,
        Thetadd: np.ndarray,
        X_guess: np.ndarray,
        metadata: dict | None = None,
    ) -> "Trajectory":
        """Build from the six actuator coordinates; the pose follows from the model's forward kinematics."""
        pose = robot.pose_motion(Theta, Thetad, Thetadd, X_guess)
        return cls(name, t, pose.q, pose.qd, pose.qdd, Theta, Thetad, Thetadd, dict(metadata or {}))

    @property
    def zeta(self) -> np.ndarray:
        """``(N, 3)`` carriage positions, m."""
        return self.Theta[:, 3:]

    @property
    def zetad(self) -> np.ndarray:
        """``(N, 3)`` carriage speeds, m/s."""
        return self.Thetad[:, 3:]

    @property
    def zetadd(self) -> np.ndarray:
        """``(N, 3)`` carriage accelerations, m/s^2."""
        return self.Thetadd[:, 3:]

    @property
    def duration(self) -> float:
        """Time span in s."""
        return float(self.t[-1] - self.t[0])

    def resample(self, rate: float) -> "Trajectory":
        """The same motion on a uniform grid at ``rate`` Hz (e.g. 250, 500, 1000).

        Every coordinate is interpolated by the quintic Hermite polynomial that matches its
        position, velocity and acceleration at the neighbouring samples (``scipy`` ``BPoly``):
        the result is C2 and its error is ``O(dt^6)`` for a smooth motion.
        """
        if rate <= 0:
            raise ValueError(f"sample rate must be positive, got {rate} Hz")
        n = int(np.floor(self.duration * rate + 1e-9)) + 1
        t = self.t[0] + np.arange(n) / rate
        out = {}
        from scipy.interpolate import BPoly     # here: a trajectory's users need not import SciPy

        for pos, vel, acc in (("X", "Xd", "Xdd"), ("Theta", "Thetad", "Thetadd")):
            stack = np.stack([getattr(self, pos), getattr(self, vel), getattr(self, acc)], axis=1)
            poly = BPoly.from_derivatives(self.t, stack)
            out[pos], out[vel], out[acc] = poly(t), poly.derivative(1)(t), poly.derivative(2)(t)
        meta = dict(self.metadata, resampled_rate_hz=rate)
        return Trajectory(self.name, t, metadata=meta, **out)
