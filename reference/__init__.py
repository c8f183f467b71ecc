"""An independent Monte-Carlo light tracer: the physical reference for real scenes.

Light goes emitter -> (optional blocker spheres) -> one glass sphere -> a receiving
plane of any position and orientation.  Pure numpy, vectorised over rays,
deterministic given a seed; it shares no code with the models it measures (only
the conventions of SPEC sections 4, 6, 9 and 10).

- :mod:`.vectors`: ray-sphere intersection (SPEC 4.3), refraction, Fresnel, frames
- :mod:`.emitters`: Blender's point, spot, sun and area lights, each sampling only
  rays that can reach the lens, weighted by their exact solid angle or area
- :mod:`.scene`: the glass sphere, the blockers and the receiving plane
- :mod:`.tracer`: :func:`trace_irradiance`, the irradiance on the plane with
  per-cell standard errors; :func:`lens_shadow`, the lens's shadow on the plane
- :mod:`.shapes`: glass solids of any shape with exact ray intersection (ellipsoid,
  biconvex or plano-convex lens, rod, box, any closed triangle mesh with its BVH);
  :mod:`.glass_meshes` tessellates the analytic ones (for Blender and mitsuba)
- :mod:`.glass_tracer`: :func:`trace_glass`, every Fresnel branch through one or
  several such solids (TIR, Beer absorption) onto receiving planes and past opaque
  blockers, with per-cell standard errors and an energy balance
"""

from __future__ import annotations

from .emitters import AreaLight, PointLight, RayBatch, SpotLight, SunLight, spot_mask
from .scene import Blocker, GlassSphere, ReceiverPlane
from .tracer import PlaneIrradiance, blocker_transmission, lens_shadow, trace_irradiance

__all__ = [
    "AreaLight",
    "Blocker",
    "GlassSphere",
    "PlaneIrradiance",
    "PointLight",
    "RayBatch",
    "ReceiverPlane",
    "SpotLight",
    "SunLight",
    "blocker_transmission",
    "lens_shadow",
    "spot_mask",
    "trace_irradiance",
]
