"""Accuracy measures: trajectories against the truth (``hmap eval traj``)."""

from ._hmap import eval as _eval

trajectory = _eval.trajectory

__all__ = ["trajectory"]
