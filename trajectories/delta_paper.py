"""The Delta paths of the SVD-DLS paper, in arm angles (rad), exact with their rates.

- :func:`verification_path` (eq. 60): one harmonic per arm, ``q = (0.5 sin(3π t/4),
  0.4 sin(6π t/5), 0.3 sin(5π t/3))``; the paper's test path.
- :func:`training_path` (eq. 84, Table 2): seven harmonics per arm at the tabulated angular
  frequencies, amplitudes ``a_ik = 0.05 w_ik`` (not printed in the paper: chosen), so that
  ``q_i = sum_k 0.05 sin(w_ik t)``.
- :func:`held_arm_path`: eq. 60 with arm 3 held at 0, the insufficient excitation on which the
  online estimators are compared (the paper's eq. 60 itself is rank-complete).

Each returns ``(q, qd, qdd)``, arrays (N, 3) in rad, rad/s, rad/s² at the times ``t`` (N,) s.
"""

from __future__ import annotations

import numpy as np

#: eq. 60: amplitudes (rad) and angular frequencies (rad/s) of the verification path
VERIFICATION_AMPLITUDES = np.array([0.5, 0.4, 0.3])
VERIFICATION_FREQUENCIES = np.array([3 * np.pi / 4, 6 * np.pi / 5, 5 * np.pi / 3])
#: Table 2: the training path's angular frequencies (rad/s), one row per arm
TRAINING_FREQUENCIES = np.array([
    [1.3205, 3.6285, 4.9051, 0.6095, 0.3655, 0.0523, 2.8992],
    [2.7838, 0.8777, 9.5607, 0.4818, 2.7921, 5.6926, 4.3036],
    [7.2655, 5.3827, 2.4944, 3.6024, 3.2002, 3.8935, 4.4653],
])
#: chosen amplitude law of the training path: ``a_ik = TRAINING_GAIN w_ik`` (rad/s), b = 0, q0 = 0
TRAINING_GAIN = 0.05


def _harmonics(t: np.ndarray, amplitude: np.ndarray, w: np.ndarray):
    """``q_i = sum_k amplitude_ik sin(w_ik t)`` (amplitude, w: (3, K)) and its rates."""
    t = np.asarray(t, dtype=float)
    arg = w[None] * t[:, None, None]
    q = np.sum(amplitude * np.sin(arg), axis=2)
    qd = np.sum(amplitude * w * np.cos(arg), axis=2)
    qdd = -np.sum(amplitude * w**2 * np.sin(arg), axis=2)
    return q, qd, qdd


def verification_path(t):
    """Eq. 60 (rad), with its exact rates."""
    return _harmonics(t, VERIFICATION_AMPLITUDES[:, None], VERIFICATION_FREQUENCIES[:, None])


def held_arm_path(t):
    """Eq. 60 with arm 3 held at ``q3 = 0``: two excited arms, a rank-deficient regressor."""
    amplitude = VERIFICATION_AMPLITUDES.copy()
    amplitude[2] = 0.0
    return _harmonics(t, amplitude[:, None], VERIFICATION_FREQUENCIES[:, None])


def training_path(t):
    """Eq. 84 with Table 2's frequencies and the chosen amplitudes ``a = 0.05 w``, ``b = 0``."""
    return _harmonics(t, np.full_like(TRAINING_FREQUENCIES, TRAINING_GAIN), TRAINING_FREQUENCIES)
