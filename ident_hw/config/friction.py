"""The ``robot.friction`` section: which friction model the joints are identified with
(:mod:`ident_hw.model.friction`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from ident_hw.model.friction import MAXWELL_ELEMENTS, MODELS

from .schema import positive, spec

# the type of FrictionConfig.model: one of ident_hw.model.friction.MODELS
if TYPE_CHECKING:     # a type checker sees text; the schema reads the models at run time
    FrictionKind = str
else:
    FrictionKind = Literal[MODELS]


@dataclass(frozen=True)
class FrictionConfig:
    """The joints' friction model, the same for every actuator.

    ``model``, the Coulomb term: ``coulomb`` (a smoothed sign, ``tanh(qd / robot.coulomb_width)``:
    the simulated rig's), ``held`` (the sign held through a stop: below ``rest_speed`` a joint keeps
    the sign of its last motion), ``dahl`` (Dahl's presliding model: the Coulomb force follows the
    position over ``presliding``, holds at a stop and passes smoothly through zero when the motion
    reverses), ``maxwell`` (the generalised Maxwell-slip model: Dahl elements in parallel, one per
    distance of ``elements``, each with its own Coulomb force). Beside it a viscous term always; ``stribeck``: a Stribeck term ``fs`` over the
    speeds of that Stribeck velocity (``false``: none); ``offset``: a constant ``f0`` per actuator
    (a drive's current offset, a seal). ``presliding`` and ``stribeck``: a value, or ``auto``: the
    one of a grid whose fit leaves the least residual on the identification data
    (:mod:`ident_hw.experiment.friction_choice`). Anything but ``coulomb`` alone is for robots read
    from their description file (``robot.kind: described``) identified from recordings; the
    simulated rig's plant has Coulomb and viscous friction only.
    """

    model: FrictionKind = "coulomb"
    offset: bool = False
    rest_speed: float = field(default=0.01, metadata=spec(positive, unit="rad/s | m/s"))
    presliding: float | Literal["auto"] = field(default="auto", metadata=spec(unit="rad | m"))
    stribeck: float | Literal["auto"] | bool = field(default=False, metadata=spec(unit="rad/s | m/s"))
    elements: tuple[float, ...] = field(default=MAXWELL_ELEMENTS, metadata=spec(positive, unit="rad | m"))

    @property
    def default(self) -> bool:
        """The simulated rig's friction: Coulomb and viscous, no offset, no Stribeck term."""
        return self.model == "coulomb" and not self.offset and self.stribeck is False
