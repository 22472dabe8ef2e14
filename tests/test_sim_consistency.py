"""The simulated plant moves as the identification's model says, at the simulation's SYNC rate.

The plant integrates the closed-chain dynamics between SYNCs; the identification differentiates
the sampled positions and fits the model's regressor to the sampled forces. If the plant's
dynamics within a period drift from the model's (they did: the mass matrix and the velocity
terms were held at their period-start values, which at 100 Hz biased the identified link
viscous friction by -5.7 %), no identification on rig data can be right. Here the plant follows
the shipped excitation at 100 Hz with the position loops of the rig, its exact positions and
forces are sampled (no encoder, current or noise: those are the rig's, tested elsewhere), and the
campaign's own base-parameter step must recover the truth.
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
""")
    config = load_config(path)
    (planned,) = plan(config, ["excitation"])
    assert config.bus.sync_rate == pytest.approx(100.0)
    rec = exact_recording(config, planned.trajectory, config.sim.max_substep)
    fit = identify(config, {"excitation": rec}).base_fit
    error = 100 * (fit.coef - fit.truth) / np.abs(fit.truth)
    assert np.abs(error).max() < 1.0, dict(zip(fit.expressions, error.round(2)))
