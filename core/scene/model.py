"""The scene model shared by the `.bi` reader/writer, phase 1 and the Blender side.

Colours are stored in 0–1; `Scene.color_scale` remembers the scale the file used
(1 or 255) so that writing a scene back gives the numbers it was read from.
"""

from __future__ import annotations

from dataclasses import dataclass, field

Vec3 = tuple[float, float, float]


@dataclass
class Surface:
    """Thesis surface block (`#C #A #D #S #T #E #N`)."""

    color: Vec3 = (1.0, 1.0, 1.0)
    ambient: float = 0.1  # ka
    diffuse: float = 0.5  # kd
    specular: float = 0.4  # ks (also global reflection)
    transmission: float = 0.0  # kt, 0 = opaque
    exponent: float = 6.0  # Phong exponent E
    ior: float = 1.0  # n


@dataclass
class Sphere:
    center: Vec3
    radius: float
    surface: Surface = field(default_factory=Surface)
    name: str = ""

    @property
    def is_lens(self) -> bool:
        """Transparent and converging: the spheres phase 1 turns into lenses."""
        return self.surface.transmission > 0.0 and self.surface.ior > 1.0


@dataclass
class Light:
    position: Vec3
    color: Vec3 = (1.0, 1.0, 1.0)
    brightness: float = 1.0
    radius: float = 0.0  # not in `.bi`; Blender's point-light radius
    name: str = ""


@dataclass
class Camera:
    position: Vec3 = (0.0, 0.0, 10.0)
    target: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov_deg: tuple[float, float] = (45.0, 45.0)  # horizontal, vertical opening


@dataclass
class Scene:
    width: int = 200
    height: int = 200
    camera: Camera = field(default_factory=Camera)
    lights: list[Light] = field(default_factory=list)
    objects: list[Sphere] = field(default_factory=list)
    color_scale: float = 1.0  # 1 or 255: the scale colours are written in
