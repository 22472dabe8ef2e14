"""ident_hw: dynamic parameter identification of the 3PRRR parallel robot over CANopen.

Packages, bottom up (``tests/test_layers.py`` checks the imports):

- :mod:`ident_hw.model`: kinematics, dynamics and regressor (pure math, imports nothing of the project);
- :mod:`ident_hw.filtering`, :mod:`ident_hw.segments`: filtering, differentiation, cutting recordings at gaps;
- :mod:`ident_hw.identification`: least squares, base parameters, the SQP mass fit, online estimators;
- :mod:`ident_hw.config`: YAML configs as typed sections;
- :mod:`ident_hw.results`: the typed results of a campaign and the results folder;
- :mod:`ident_hw.report`: terminal tables, plots, HTML page, MATLAB export of a results folder;
- :mod:`ident_hw.experiment`: the runner, the only place that wires bus, trajectories, recording
  and identification together;
- :mod:`ident_hw.cli`: the ``ident-hw`` command (thin; nothing imports it).

The drive layer is :mod:`drivers`, the trajectories :mod:`trajectories`; the user documentation
is in the repository's ``docs/``.
"""

__version__ = "0.1.0"
