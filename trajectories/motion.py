"""The :class:`~ident_hw.model.motion.SampledMotion` record: coordinates sampled with their first
two derivatives, what the trajectories' generators (paths, sines, the quintic timing law) return
instead of a bare ``(q, qd, qdd)`` triple. It is the robot model's record (the 3PRRR's
``actuated_motion`` and ``pose_motion`` return it too), written once there and named here for the
generators."""

from __future__ import annotations

from ident_hw.model.motion import SampledMotion

__all__ = ["SampledMotion"]
