"""Readers of the formats the hmap CLI reads, returning numpy arrays."""

from ._hmap import io as _io

read_cloud = _io.read_cloud
read_poses = _io.read_poses

__all__ = ["read_cloud", "read_poses"]
