"""The visibility step: a scene loaded once (``load_scene``) and cast for each epoch (``VisibilityOptions``).

It sits between the geometry (core/scene, core/multipath) and its users: the visibility node, the offline
loop (core/simulation.py) and the commands; the receiver (core/receiver) takes its results, never imports it.
"""
from .options import VisibilityOptions
from .scene_cache import SCENE_LOADS, load_scene

__all__ = ["SCENE_LOADS", "VisibilityOptions", "load_scene"]
