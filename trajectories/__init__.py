"""Excitation and validation trajectories for the 3PRRR, with feasibility checks."""
