"""Joint friction models: the friction columns of the regressor, per actuator, along a motion.

Every model is linear in its coefficients, so identification stays least squares; what differs
is the shape of the Coulomb term ``fc * s`` (``s`` in [-1, 1]) and which extra terms each
actuator gets. The friction force of actuator ``j`` (N·m or N) is::

    tau_f = fv * qd + fc * s(...) [+ fs * s(...) * exp(-(qd / v_s)^2)] [+ f0]

with ``qd`` its rate (rad/s, m/s). The Coulomb term's models (:data:`MODELS`):

* ``coulomb``: ``s = tanh(qd / width)``, a smoothed sign; at rest it says 0 (what the simulated
  rig's plant does). The default; on a real joint at rest it explains nothing.
* ``held``: ``s = sign(qd)`` while ``|qd| > rest_speed``, and the last such sign while the joint
  is slower: a Coulomb force that holds its sign through a stop (a joint at rest keeps whatever
  friction its last motion left; Bittencourt & Gunnarsson, "Static friction in a robot joint:
  modeling and identification of load and temperature effects", J. Dyn. Sys. 2012, sec. 2).
* ``dahl``: Dahl's presliding model (Dahl, "A solid friction model", 1968; Olsson et al.,
  "Friction models and friction compensation", Eur. J. Control 1998, sec. 3.3):
  ``dz/dq = (1 - z sign(dq)) / presliding``, the friction ``fc * z``. Moving one way, ``z`` tends
  to ``sign(dq)`` over a distance of a few ``presliding``; at rest it keeps its value (a stop holds
  the friction of the motion before it); reversing, it passes through 0 smoothly instead of
  jumping. With ``presliding`` → 0 it becomes ``held``. Integrated exactly over each sample's
  position step (constant direction within a step): ``z' = s - (s - z) exp(-|dq| / presliding)``.
* ``maxwell``: the generalised Maxwell-slip model (Lampaert, Al-Bender and Swevers, "A generalized
  Maxwell-slip friction model appropriate for control purposes", PhysCon 2003; Al-Bender et al.,
  "The generalized Maxwell-slip model", IEEE TAC 2005): several Dahl elements in parallel, each
  with its own presliding distance (``elements``, rad | m) and its own Coulomb force (``fc`` for
  the first, ``fc2``, ``fc3``, ... for the others). A joint's friction turns over several
  distances at once: a little at once (the gear's teeth), the rest over more travel (its
  compliance); a micro-motion at a stop moves the short elements only. Still linear in the
  forces: no distance is fitted, the elements span the range.

With a Stribeck velocity ``v_s`` any of them gets a Stribeck term ``fs * s * exp(-(qd / v_s)^2)``
(Armstrong-Hélouvry, "Control of machines with friction", 1991; Bittencourt & Gunnarsson 2012,
eq. 2): the friction near rest differs from the sliding one, over speeds of about ``v_s``; ``fs``
of either sign: more force at low speed (``fs > 0``, the classic Stribeck dip), or less, the
force rising to its sliding level over ``v_s`` (``fs < 0``, as a strain-wave gear's does).

``offset`` adds per actuator a constant ``f0`` (N·m, N): a current offset of the drive, or a
friction that does not change sign (a seal, a cable), as real joints have.

The history-dependent models (``held``, ``dahl``, ``maxwell``) read the rows of :meth:`FrictionModel.columns`
as consecutive samples of one motion; the state starts at 0 (unknown) and
:meth:`FrictionModel.state_known` says from which row on each actuator's state follows from the
motion seen. Pure NumPy; SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the Coulomb term's models, in the order the documentation lists them
MODELS = ("coulomb", "held", "dahl", "maxwell")
#: the models whose Coulomb term depends on the motion before each sample
HISTORY_MODELS = frozenset({"held", "dahl", "maxwell"})
#: rad | m, the Maxwell-slip elements' presliding distances where none are given (a factor 5
#: apart: from a gear's teeth to its compliance)
MAXWELL_ELEMENTS = (2e-5, 1e-4, 5e-4, 2.5e-3)
#: distances (in ``presliding``) after which a Dahl state has forgotten where it started (e^-3 = 5 %)
SETTLED_PRESLIDING = 3.0


@dataclass(frozen=True)
class FrictionModel:
    """One friction model for every actuator of a robot (see the module docstring).

    Attributes:
        kind: the Coulomb term's model, one of :data:`MODELS`.
        width: rad/s | m/s, the smoothing of ``tanh(qd / width)`` (``coulomb``).
        rest_speed: rad/s | m/s, below it a ``held`` Coulomb term keeps its last sign.
        presliding: rad | m, Dahl's presliding distance (``dahl``): one for every actuator, or
            one per actuator.
        stribeck_velocity: rad/s | m/s, the Stribeck velocity ``v_s`` (one, or one per
            actuator); None: no Stribeck term.
        offset: each actuator gets a constant friction ``f0``.
        elements: rad | m, the Maxwell-slip elements' presliding distances (``maxwell``).
    """

    kind: str = "coulomb"
    width: float = 1e-3
    rest_speed: float = 0.01
    presliding: float | tuple[float, ...] = 5e-4
    stribeck_velocity: float | tuple[float, ...] | None = None
    offset: bool = False
    elements: tuple[float, ...] = MAXWELL_ELEMENTS

    def __post_init__(self) -> None:
        if self.kind not in MODELS:
            raise ValueError(f"friction model must be one of {MODELS}, got {self.kind!r}")
        for name in ("width", "rest_speed", "presliding", "stribeck_velocity"):
            value = getattr(self, name)
            if value is not None and not np.all(np.asarray(value) > 0):
                raise ValueError(f"friction {name} must be positive, got {value}")
        if not self.elements or not all(e > 0 for e in self.elements):
            raise ValueError(f"friction elements must be positive distances, got {self.elements}")

    @property
    def extra_terms(self) -> tuple[str, ...]:
        """The drive terms this model adds per actuator beyond ``fv``, ``fc`` (and the rotor's
        ``Jm``), in the order they follow those in a parameter vector: the Maxwell-slip elements
        after the first (``fc2``, ``fc3``, ...), ``fs`` (Stribeck), ``f0``."""
        elements = tuple(f"fc{k}" for k in range(2, len(self.elements) + 1)) if self.kind == "maxwell" else ()
        return elements + (("fs",) if self.stribeck_velocity is not None else ()) + (("f0",) if self.offset else ())

    @property
    def history(self) -> bool:
        """The Coulomb term depends on the motion before a sample (``held``, ``dahl``)."""
        return self.kind in HISTORY_MODELS

    def coulomb(self, Theta: np.ndarray, Thetad: np.ndarray) -> np.ndarray:
        """(N, n) the Coulomb term ``s`` in [-1, 1] of each actuator along a motion: positions
        ``Theta`` and rates ``Thetad`` (N, n), consecutive samples for ``held`` and ``dahl``."""
        Thetad = np.asarray(Thetad, dtype=float)
        if self.kind == "coulomb":
            return np.tanh(Thetad / self.width)
        if self.kind == "held":
            return _held_sign(Thetad, self.rest_speed)
        if self.kind == "maxwell":
            return _dahl(np.asarray(Theta, dtype=float), np.asarray(self.elements[0], dtype=float))
        return _dahl(np.asarray(Theta, dtype=float), np.asarray(self.presliding, dtype=float))

    def columns(self, Theta: np.ndarray, Thetad: np.ndarray) -> dict[str, np.ndarray]:
        """The friction columns per drive term (``fv``, ``fc`` and :attr:`extra_terms`), each
        (N, n): the force of actuator ``j`` per unit of that term's coefficient."""
        Thetad = np.asarray(Thetad, dtype=float)
        s = self.coulomb(Theta, Thetad)
        out = {"fv": Thetad, "fc": s}
        if self.kind == "maxwell":
            for k, distance in enumerate(self.elements[1:], start=2):
                out[f"fc{k}"] = _dahl(np.asarray(Theta, dtype=float), np.asarray(distance, dtype=float))
        if self.stribeck_velocity is not None:
            out["fs"] = s * np.exp(-(Thetad / np.asarray(self.stribeck_velocity, dtype=float)) ** 2)
        if self.offset:
            out["f0"] = np.ones_like(Thetad)
        return out

    def state_known(self, Theta: np.ndarray, Thetad: np.ndarray) -> np.ndarray:
        """(N, n) bool: the friction state of each actuator follows from the motion seen since
        the first row (always for the memoryless models; ``held``: from the first row faster
        than ``rest_speed``; ``dahl``: once the actuator has travelled
        :data:`SETTLED_PRESLIDING` presliding distances)."""
        Thetad = np.asarray(Thetad, dtype=float)
        if self.kind == "held":
            return np.logical_or.accumulate(np.abs(Thetad) > self.rest_speed, axis=0)
        if self.kind in ("dahl", "maxwell"):
            Theta = np.asarray(Theta, dtype=float)
            travelled = np.zeros_like(Theta)
            travelled[1:] = np.cumsum(np.abs(np.diff(Theta, axis=0)), axis=0)
            longest = max(self.elements) if self.kind == "maxwell" else np.asarray(self.presliding, dtype=float)
            return travelled >= SETTLED_PRESLIDING * longest
        return np.ones(Thetad.shape, dtype=bool)


def _held_sign(Thetad: np.ndarray, rest_speed: float) -> np.ndarray:
    """(N, n) ``sign(qd)`` where ``|qd| > rest_speed``, else the last such sign (0 before any)."""
    moving = np.abs(Thetad) > rest_speed
    idx = np.where(moving, np.arange(len(Thetad))[:, None], -1)
    last = np.maximum.accumulate(idx, axis=0)
    signs = np.sign(Thetad)
    out = np.take_along_axis(signs, np.maximum(last, 0), axis=0)
    return np.where(last >= 0, out, 0.0)


def _dahl(Theta: np.ndarray, presliding: np.ndarray) -> np.ndarray:
    """(N, n) Dahl's state along positions ``Theta`` (N, n), from 0 at the first row, each
    sample's step integrated exactly (see the module docstring); ``presliding``: one distance,
    or (n,)."""
    out = np.zeros_like(Theta)
    if len(Theta) < 2:
        return out
    step = np.diff(Theta, axis=0)
    direction = np.sign(step)
    decay = np.exp(-np.abs(step) / presliding)
    z = np.zeros(Theta.shape[1])
    for k in range(len(step)):
        z = direction[k] - (direction[k] - z) * decay[k]
        out[k + 1] = z
    return out
