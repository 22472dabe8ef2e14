"""Base parameters as combinations of the physical ones: the one (kept, H) type of the project.

A robot's regressor ``Y`` (…, n) has fewer independent columns than parameters; its r base
parameters are ``pi_b = H @ pi`` with ``H`` (r, n), and row i is named after the parameter
``kept[i]`` whose column carries it (``Y @ pi == Y[..., kept] @ (H @ pi)``). The model gives such
a basis in closed form (the Delta's readable set, :func:`ident_hw.model.delta.closed_form_base`)
or finds it numerically (a described robot, :func:`ident_hw.model.described.numerical_base`); the
identification finds one from the data by SVD
(:class:`ident_hw.identification.base_params.BaseParameters`, which adds the rank decision's
figures to this type).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .combinations import format_combination


@dataclass(frozen=True)
class BaseBasis:
    """Base parameters ``pi_b = H @ pi``.

    Attributes:
        names: (n,) the physical parameters, in the order of ``H``'s columns.
        kept: (r,) the parameter whose regressor column carries each base parameter.
        H: (r, n) base parameters ``pi_b = H @ pi``; row i has 1 at ``kept[i]`` (units: each
            coefficient is the ratio of the kept parameter's unit to its column's).
    """

    names: tuple[str, ...]
    kept: tuple[str, ...]
    H: np.ndarray

    @property
    def expressions(self) -> tuple[str, ...]:
        """(r,) each base parameter as a readable combination, e.g. ``"I_l1 + 0.0225 m_l1"``."""
        return tuple(format_combination(row, self.names) for row in self.H)

    def reduce(self, pi: np.ndarray) -> np.ndarray:
        """Base-parameter values ``H @ pi`` of a physical parameter vector (n,) → (r,)."""
        return self.H @ np.asarray(pi, dtype=float)

    def on_columns(self, names) -> np.ndarray:
        """``H`` (r, len(names)) with its columns in the order of ``names`` (the same parameters
        as :attr:`names`, perhaps reordered).

        Raises:
            ValueError: ``names`` are not the basis's parameters (naming those that differ).
        """
        names = tuple(names)
        if sorted(names) != sorted(self.names):
            differ = sorted(set(names) ^ set(self.names))
            raise ValueError(f"a base basis over {len(self.names)} parameters used for {len(names)} others "
                             f"(differing: {differ[:5]})")
        return self.H[:, [self.names.index(n) for n in names]]
