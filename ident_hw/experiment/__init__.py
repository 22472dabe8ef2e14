"""The experiment runner: the one part of the project that wires the bus, the drives (or the
simulated rig), the trajectories, the recordings and the identification together.

- :mod:`.runner`: ``run_campaign`` (plan, move, stream, record, identify, report) on one bus;
- :mod:`.plan`: the campaign's trajectories from the config, checked before any motion;
- :mod:`.session`: the configured bus opened, with the in-process simulated rig on it;
- :mod:`.offline`: ``identify`` of recordings (the steps of ``identification:``);
- :mod:`.campaign_estimator`: the online estimators along a campaign;
- :mod:`.quality`: the verdict that decides ``complete`` or ``degraded``;
- :mod:`.recordings`, :mod:`.folders`, :mod:`.inspection`, :mod:`.interrupts`: recordings checked against
  the config, the results folder, read-only looks at the bus (scan, monitor), Ctrl-C/SIGTERM handling.

May import everything below it (model, identification, config, results, report, drivers,
trajectories); only the CLI imports it.
"""
