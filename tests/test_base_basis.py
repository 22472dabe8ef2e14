"""One base-parameter type (issue 49): the model's closed-form and numerical bases and the
identification's SVD result are all :class:`ident_hw.model.base_basis.BaseBasis`."""
from __future__ import annotations

import numpy as np
import pytest

from ident_hw.identification.base_params import BaseParameters, base_parameters, identify_base, with_basis
from ident_hw.model.base_basis import BaseBasis
from ident_hw.model.delta import PARAM_NAMES, Delta, closed_form_base

NAMES = ("a", "b", "c")


def _regressor(n: int = 200, seed: int = 1) -> np.ndarray:
    """(n, 1, 3) columns x, y, 2x: only ``a + 2 c`` and ``b`` are identifiable."""
    rng = np.random.default_rng(seed)
    x, y = rng.standard_normal(n), rng.standard_normal(n)
    return np.stack([x, y, 2 * x], axis=1)[:, None, :]


def test_every_base_is_the_one_type():
    assert isinstance(closed_form_base(), BaseBasis) and closed_form_base().names == PARAM_NAMES
    assert isinstance(Delta().readable_base(), BaseBasis)
    base = base_parameters(_regressor()[:, 0, :], NAMES)
    assert isinstance(base, BaseBasis) and isinstance(base, BaseParameters)


def test_a_basis_given_in_another_parameter_order_is_put_in_the_data_s():
    Y = _regressor()
    pi = np.array([0.5, -1.0, 0.25])
    tau = Y @ pi
    # the basis written by hand over (c, b, a): rows "c + 0.5 a" (named after c) and "b"
    basis = BaseBasis(("c", "b", "a"), ("c", "b"), np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.0]]))
    base, fit = identify_base(Y, tau, NAMES, basis=basis)
    assert base.kept == ("c", "b")
    assert np.array_equal(base.H, np.array([[0.5, 0.0, 1.0], [0.0, 1.0, 0.0]]))    # columns a, b, c
    assert base.expressions == ("0.5 a + c", "b")
    # the estimate: c + a / 2 = 0.25 + 0.25, b = -1 (exact data)
    assert fit.coef == pytest.approx([0.5, -1.0], abs=1e-12)


def test_a_basis_over_other_parameters_is_refused_by_name():
    numeric = base_parameters(_regressor()[:, 0, :], NAMES)
    other = BaseBasis(("a", "b", "d"), ("a", "b"), np.eye(2, 3))
    with pytest.raises(ValueError, match="differing: \\['c', 'd'\\]"):
        with_basis(numeric, other)
    # a basis of the right parameters but another rank is not used
    assert with_basis(numeric, BaseBasis(NAMES, ("a",), np.array([[1.0, 0.0, 2.0]]))) is None
