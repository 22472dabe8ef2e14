"""The one-state dynamics of the simulator's inner loop (ident_hw.model.single) against the
vectorised model: forward kinematics, mass matrix and velocity terms at random states."""

import numpy as np

import nominal
from ident_hw.model import KinematicsError, ThreePRRR
from ident_hw.model.single import SingleState

ROBOT = ThreePRRR(nominal.GEOMETRY)
PARAMS = nominal.TRUE_PARAMS


def _states(n, seed=0):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(-0.05, 0.05, n), rng.uniform(-0.05, 0.05, n), rng.uniform(-0.3, 0.3, n)])
    zeta = rng.uniform(-0.05, 0.05, (n, 3))
    theta, _ = ROBOT.inverse_kinematics(X, zeta)
    Theta = np.column_stack([theta, zeta])
    Thetad = rng.normal(0, [1.0, 1.0, 1.0, 0.2, 0.2, 0.2], (n, 6))
    return X, Theta, Thetad


def test_mass_matrix_and_velocity_terms_equal_the_vectorised_model():
    X, Theta, Thetad = _states(40)
    single = SingleState(ROBOT.kinematics)
    guess = X + 1e-3      # Newton from a nearby pose, as the plant continues from the last one
    motion = ROBOT.motion_from_actuated(Theta, Thetad, np.zeros_like(Theta), guess)
    M_ref, c_ref = ROBOT.reduced_dynamics_of(motion, PARAMS)
    c_ref = c_ref - ROBOT.friction(Thetad, PARAMS)
    for k in range(len(X)):
        state = single.reduced_dynamics(Theta[k], Thetad[k], PARAMS, guess[k])
        M, c, pose = state.M, state.bias, state.pose
        np.testing.assert_allclose(pose, X[k], atol=1e-12)
        np.testing.assert_allclose(M, M_ref[k], rtol=1e-11, atol=1e-12 * np.abs(M_ref[k]).max())
        np.testing.assert_allclose(c, c_ref[k], rtol=1e-9, atol=1e-10 * np.abs(c_ref[k]).max())


def test_far_guesses_end_as_the_vectorised_forward_kinematics():
    """From far guesses Newton may land on another working or assembly mode: both routes then
    refuse it, or both find the same pose."""
    X, Theta, _ = _states(1, seed=3)
    single = SingleState(ROBOT.kinematics)
    rng = np.random.default_rng(7)
    outcomes = set()
    for _ in range(60):
        guess = X[0] + rng.normal(0, [0.1, 0.1, 1.5])
        try:
            ref = ROBOT.forward_kinematics(Theta, guess)[0]
        except KinematicsError:
            ref = None
        try:
            pose = single.forward_kinematics(Theta[0], guess)[0]
        except KinematicsError:
            pose = None
        assert (ref is None) == (pose is None), (guess, ref, pose)
        if ref is not None:
            np.testing.assert_allclose(pose, ref, atol=1e-10)
        outcomes.add(ref is None)
    assert outcomes == {True, False}   # both outcomes were exercised
