"""The physical size of the parameters (``ident_hw.identification.physical_size``), against
independent computations: a described robot's bodies from pinocchio's own inertias (mass,
centre of mass, inertia about it), the 3PRRR's planar bodies from their table, combinations and
the well-identified rule by hand."""

from pathlib import Path

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.config.robots import initial_parameters, model_of
from ident_hw.identification.physical_size import combination_sizes, parameter_sizes, well_identified
from ident_hw.model.pseudo_inertia import SPATIAL
from ident_hw.results.folder import BaseFitFile
from ident_hw.results.objects import BaseFit

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def test_a_described_robots_sizes_are_its_bodies_mass_and_radius_of_gyration():
    """Every body of the Stewart platform: ``m``, ``m l``, ``m l²`` with ``l²`` the mean squared
    distance of its mass from the joint frame's origin, ``(tr(I_c) / 2 + m |c|²) / m`` from
    pinocchio's inertia about the centre of mass ``I_c`` and the centre ``c`` (not from the
    dynamic parameters the code reads)."""
    robot = model_of(load_config(CONFIGS / "robot-stewart.yaml").robot)
    cad = robot.nominal_parameters()
    sizes = parameter_sizes(robot.physical_bodies(), cad)
    massive = 0
    for k in range(len(robot.body_names)):
        inertia = robot.model.inertias[k + 1]
        m, c, Ic = inertia.mass, np.asarray(inertia.lever), np.asarray(inertia.inertia)
        l2 = (0.5 * np.trace(Ic) + m * c @ c) / m if m > 0 else 0.0
        expected = [m if v == "m" else m * np.sqrt(l2) if v in ("mx", "my", "mz") else m * l2 for v in SPATIAL]
        np.testing.assert_allclose(sizes[10 * k:10 * k + 10], expected, rtol=1e-12, atol=0.0)
        massive += m > 0
    assert massive == len(robot.body_names)          # the shipped file gives every body its mass
    # the drive terms: their CAD magnitudes (viscous and Coulomb friction 0 in the file, rotor inertia not)
    drive = slice(10 * len(robot.body_names), None)
    np.testing.assert_array_equal(sizes[drive], np.abs(cad[drive]))


def test_the_3prrr_planar_bodies_sizes_are_their_masses_and_inertias():
    """The 3PRRR's bodies sit in frames at their centres of mass (``l² = I_zz / m``): the size of
    a mass is the mass, of an inertia the inertia itself; a carriage (a point mass) gives its mass
    only; friction has no CAD value (0)."""
    robot_config = load_config(CONFIGS / "robot-3prrr.yaml").robot
    robot = model_of(robot_config)
    cad = initial_parameters(robot_config)
    sizes = dict(zip(robot.parameter_names, parameter_sizes(robot.physical_bodies(), cad)))
    values = dict(zip(robot.parameter_names, cad))
    for name in ("m_c", "m_l1", "m_l2", "m_ee", "I_l1", "I_l2", "I_ee"):
        assert sizes[name] == pytest.approx(abs(values[name]), rel=1e-12), name
    assert all(sizes[n] == abs(values[n]) for n in robot.parameter_names if n.startswith(("fv_", "fc_")))


def test_a_combinations_size_is_the_rms_of_its_terms_at_their_sizes():
    H = np.array([[1.0, 1.0, 0.0], [0.0, -0.5, 2.0], [0.0, 0.0, 0.0]])
    s = np.array([3.0, 4.0, 0.25])
    np.testing.assert_allclose(combination_sizes(H, s), [5.0, np.hypot(2.0, 0.5), 0.0], rtol=1e-15)


def test_well_identified_takes_the_larger_of_the_estimate_and_the_size():
    coef = np.array([0.0, 1e-4, 2.0, 2.0, 0.0, 1.0])
    sigma = np.array([0.009, 0.009, 0.15, 0.25, 0.001, np.nan])
    size = np.array([0.1, 0.1, 0.1, 0.1, 0.0, 10.0])
    np.testing.assert_array_equal(well_identified(coef, sigma, size, 10.0), [True, True, True, False, False, False])
    # without sizes: the relative sigma alone (an estimate of 0 is never well identified)
    np.testing.assert_array_equal(well_identified(coef, sigma, None, 10.0), [False, False, True, False, False, False])


def test_a_base_fit_keeps_its_sizes_and_verdicts_through_its_file():
    fit = BaseFit(step="base", method="WLS", trajectories=("excitation",), expressions=("a", "b + c"),
                  H=np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]]), coef=np.array([0.0, 1.0]),
                  sigma=np.array([0.005, 0.5]), initial=np.zeros(2), truth=None, held=(), unexcited=(),
                  threshold=10.0, size=np.array([0.1, 2.0]))
    np.testing.assert_array_equal(fit.well_identified_mask, [True, False])
    back = BaseFitFile.of(fit).fit()
    np.testing.assert_array_equal(back.size, fit.size)
    np.testing.assert_array_equal(back.well_identified_mask, fit.well_identified_mask)
    assert [r.size for r in back.rows()] == [0.1, 2.0]
