"""The simulated plant moves as the identification's model says, at the simulation's SYNC rate.

The plant integrates the closed-chain dynamics between SYNCs; the identification differentiates
the sampled positions and fits the model's regressor to the sampled forces. If the plant's
motion within a period drifts from the model's, no identification on rig data can be right:
the forces are exact at the SYNC instants only, the differenced accelerations carry whatever the
motion did in between. Here the plant follows a campaign path under the emulated drives' demand
and position loops, its exact positions and forces are sampled (no encoder, current or noise:
those are the rig's, tested elsewhere), and the campaign's own base-parameter step must recover
the truth: the 3PRRR's shipped excitation at 100 Hz, and the Delta's training path at 500 Hz,
whose rods' products of inertia are so weakly represented in the torques that an acceleration
error of 0.1 % of the acceleration moves them by several percent.

The differenced accelerations themselves are compared with the plant's exact ones in
``tests/test_sim_plant.py``.
"""

import numpy as np
import pytest

from ident_hw.config import load_config
from ident_hw.experiment.offline import identify
from ident_hw.experiment.plan import plan
from ident_hw.model import ThreePRRR

from ident_scenarios import CONFIGS, exact_recording

CYCLES = 4
NAMES = ThreePRRR.parameter_names


@pytest.mark.slow
def test_base_parameters_from_exact_plant_samples_at_100hz_match_the_truth(tmp_path):
    path = tmp_path / "sim.yaml"
    path.write_text(f"""extends: {CONFIGS / 'sim-3prrr.yaml'}
bus: {{interface: virtual, channel: unused, sync_rate: 100.0}}
trajectories:
  - {{name: excitation, kind: fourier, cycles: {CYCLES}}}
identification:
  steps:
    - {{name: base, trajectories: [excitation], method: wls, parameters: [{", ".join(NAMES)}]}}
  validation: []
  encoder_draws: 0        # exact positions: no encoder rounding to read again or to correct for
""")
    config = load_config(path)
    (planned,) = plan(config, ["excitation"])
    assert config.bus.sync_rate == pytest.approx(100.0)
    rec = exact_recording(config, planned.trajectory, config.sim.max_substep)
    fit = identify(config, {"excitation": rec}).base_fit
    error = 100 * (fit.coef - fit.truth) / np.abs(fit.truth)
    assert np.abs(error).max() < 1.0, dict(zip(fit.expressions, error.round(2)))


@pytest.mark.slow
def test_delta_base_parameters_from_exact_plant_samples_match_the_truth(tmp_path):
    """The campaign's training path (60 s of it) at the config's 500 Hz: worst 0.67 % measured."""
    training = next(t for t in load_config(CONFIGS / "sim-delta.yaml").trajectories if t.name == "training")
    path = tmp_path / "delta.yaml"
    path.write_text(f"""extends: {CONFIGS / 'sim-delta.yaml'}
bus: {{interface: virtual, channel: unused}}
trajectories:
  - {{name: training, kind: delta_training, duration: 60.0, amplitude: {list(training.amplitude)}, bandwidth: 2.0}}
identification: {{validation: [], online: {{in_run: false}}, encoder_draws: 0}}   # exact positions
""")
    config = load_config(path)
    (planned,) = plan(config, ["training"])
    assert config.bus.sync_rate == pytest.approx(500.0)
    rec = exact_recording(config, planned.trajectory, None)
    fit = identify(config, {"training": rec}).base_fit
    nonzero = np.abs(fit.truth) > 0
    error = 100 * (fit.coef[nonzero] - fit.truth[nonzero]) / np.abs(fit.truth[nonzero])
    assert nonzero.sum() >= 30
    assert np.abs(error).max() < 2.0, dict(zip(np.asarray(fit.expressions)[nonzero], error.round(2)))
