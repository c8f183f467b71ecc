"""The scene as phase 1 reads it: lights and lenses as columns of numbers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Scene


@dataclass
class SceneArrays:
    """The numbers phase 1 needs, as arrays (lights L, spheres S)."""

    light_position: np.ndarray  # (L, 3)
    light_brightness: np.ndarray  # (L,)
    light_color: np.ndarray  # (L, 3)
    center: np.ndarray  # (S, 3)
    radius: np.ndarray  # (S,)
    ior: np.ndarray  # (S,)
    kt: np.ndarray  # (S,)

    @classmethod
    def from_scene(cls, scene: Scene) -> SceneArrays:
        def arr(values, shape):
            return np.asarray(values, dtype=float).reshape(shape)

        nl, ns = len(scene.lights), len(scene.objects)
        return cls(
            light_position=arr([lt.position for lt in scene.lights], (nl, 3)),
            light_brightness=arr([lt.brightness for lt in scene.lights], (nl,)),
            light_color=arr([lt.color for lt in scene.lights], (nl, 3)),
            center=arr([s.center for s in scene.objects], (ns, 3)),
            radius=arr([s.radius for s in scene.objects], (ns,)),
            ior=arr([s.surface.ior for s in scene.objects], (ns,)),
            kt=arr([s.surface.transmission for s in scene.objects], (ns,)),
        )
