"""Random `.bi`-like scenes for comparison tests (phase 1, tier tables, the CLI):
lights and spheres of every kind, plus a collimated and a virtual case."""

import numpy as np

from core.scene.model import Light, Scene, Sphere, Surface


def random_scene(seed, n_lights=3, n_spheres=40, spread=6.0):
    rng = np.random.default_rng(seed)
    lights = [
        Light(
            position=tuple(rng.uniform(-spread, spread, 3).tolist()),
            color=tuple(rng.uniform(0, 1, 3).tolist()),
            brightness=float(rng.uniform(0.1, 2)),
            radius=float(rng.uniform(0, 0.2)),
        )
        for _ in range(n_lights)
    ]
    objects = [
        Sphere(
            center=tuple(rng.uniform(-spread, spread, 3).tolist()),
            radius=float(rng.uniform(0.05, 1.0)),
            surface=Surface(
                transmission=float(rng.choice([0.0, 0.4, 0.9, 1.0])),
                ior=float(rng.choice([0.9, 1.1, 1.33, 1.5, 2.4])),
            ),
        )
        for _ in range(n_spheres)
    ]
    # A light at a lens's focal point (collimated: D = 1/P = 1.5 R for n = 1.5) and
    # lenses far away and inside the focal length (virtual).
    lights.append(Light(position=(100.0, 100.0, 100.0)))
    objects += [
        Sphere(
            center=(101.5, 100.0, 100.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.5)
        ),
        Sphere(
            center=(100.0, 125.45, 100.0),
            radius=1.0,  # 1/P = 25.5
            surface=Surface(transmission=1.0, ior=1.02),
        ),
        Sphere(center=(40.0, 0.0, 0.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.5)),
        Sphere(center=(0.0, 40.0, 0.0), radius=1.0, surface=Surface(transmission=1.0, ior=1.02)),
    ]
    return Scene(lights=lights, objects=objects)
