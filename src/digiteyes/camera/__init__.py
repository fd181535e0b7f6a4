"""Cameras: projection models with Jacobians, and rigs of several cameras."""

from digiteyes.camera.camera import PROJECTIONS, Camera, Projection
from digiteyes.camera.rig import Rig, load_rig, save_rig

__all__ = ["PROJECTIONS", "Camera", "Projection", "Rig", "load_rig", "save_rig"]
