"""Pure numeric conversions between the thesis' `.bi` scene and Blender's data.

Used by the `.bi` importer/exporter (blender/bi/operators.py, blender/bi/scene_data.py)
and by anything that reads Blender lights and materials back as a `.bi` scene. No bpy
here: every rule is tested without Blender (tests/core/bi/test_bi_conversions.py).

Rules (also in the README):

Units: one `.bi` unit is one Blender unit (metre).

Camera:
  * the camera sits at `C`, looks at `A` (Blender cameras look along local −Z, with
    local +Y up); `U` need not be perpendicular to the view: the camera's up is `U`
    made perpendicular to it (Gram–Schmidt), as in the thesis' ray tracer.
  * opening angles `B h v` → `sensor_fit = 'HORIZONTAL'`, `sensor_width` 36 mm and
    `lens = (sensor_width / 2) / tan(h / 2)` (the sensor widens if that would fall
    below Blender's 1 mm minimum); the vertical angle is honoured through the
    render's pixel aspect: `pixel_aspect_x / pixel_aspect_y =
    tan(h/2)·H / (tan(v/2)·W)` (both 1 when the angles match the image's shape,
    as in all the thesis' scenes).
  * `V w h` → render resolution w × h at 100 %.
  * the distance to the target is kept as the camera's focus distance.

Point lights: colour as in the file (0–1: the reader divides 0–255 files by 255);
  `power [W] = brightness × WATTS_PER_BRIGHTNESS` (10 000 W). Blender's point light
  is radiometric: a white matte surface facing a light of power P at distance d
  shows `P / (4π² d²)`, so a light of brightness 1 and colour 1 makes it exactly 1
  at `d = sqrt(10 000) / (2π) ≈ 15.9` units, the distance at which the thesis'
  three scenes place their light from the objects it lights (12–17 units), so
  they render well exposed. (The thesis' own `1/(d + k)` attenuation has no
  physical counterpart; Blender's light falls off as 1/d².)

Materials (Principled BSDF), from the surface block `#C #A #D #S #T #E #N`:

  ===================  ========================================================
  Base Color           #C (the surface colour, 0–1) when kt = 0; white when
                       kt > 0: the thesis refracts untinted (a secondary source
                       has the light's colour) and Blender tints what a
                       Principled BSDF transmits by its Base Color
  Viewport Display     #C (the material's viewport colour, `diffuse_color`)
  Transmission Weight  kt
  IOR                  n when kt > 0; 1.5 (a plain dielectric's highlight) when
                       kt = 0, where n has no meaning in the thesis
  Metallic             0 when kt > 0; otherwise ks / (kd + ks) (0 when both are 0):
                       the thesis' "mirror-like" spheres (kd 0, ks 0.8) are metals
  Roughness            0 when kt > 0 (the thesis refracts and reflects without
                       blur); otherwise sqrt(2 / (E + 2)), the Beckmann slope of a
                       Phong lobe of exponent E
  ka                   no input: Blender's world light is the ambient term
  ===================  ========================================================

  Back from a Principled BSDF (a material not made by the importer):
  `#C` = Base Color when kt = 0, the viewport colour when kt > 0; `kt` =
  Transmission Weight, `n` = IOR when kt > 0 else 1,
  `ks = m (1 − kt)`, `kd = (1 − m)(1 − kt)` with m = Metallic (0 when kt > 0),
  `E = 2 / r² − 2` for roughness r (capped at MAX_EXPONENT; the thesis' glass
  exponent 80 when kt > 0 or r = 0), `ka` = 0.1 (the thesis' usual).
  The importer also stores each record's numbers on the Blender data; the exporter
  writes those back while Blender's values still match them (`prefer_stored`), so
  that import → export gives the file's numbers although Blender keeps float32.

World: the thesis lit with an ambient light of colour 0.1 0.1 0.1: the importer
  makes the world's background that colour (AMBIENT_COLOR).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.model import Camera, Surface

#: Blender watts of a point light per unit of `.bi` brightness.
WATTS_PER_BRIGHTNESS = 10_000.0
#: The thesis' ambient light colour, used as the world's colour.
AMBIENT_COLOR = (0.1, 0.1, 0.1)
#: Default sensor width (mm), Blender's own.
SENSOR_WIDTH = 36.0
#: Blender's limits: focal length and sensor sizes >= 1 mm, pixel aspect in [1, 200],
#: resolution in [4, 65536].
MIN_LENS = 1.0
MIN_SENSOR = 1.0
MAX_PIXEL_ASPECT = 200.0
MIN_RESOLUTION, MAX_RESOLUTION = 4, 65536
#: Phong exponent given to a perfectly smooth surface (roughness 0) read back.
MAX_EXPONENT = 10_000.0
#: Exponent read back for a transmitting sphere (glass has roughness 0 here): the
#: thesis' glass spheres all use 80.
GLASS_EXPONENT = 80.0
#: ka read back from a Blender material (no counterpart): the thesis' usual value.
DEFAULT_AMBIENT = 0.1
#: IOR given to opaque spheres (n is meaningless when kt = 0).
OPAQUE_IOR = 1.5


# --------------------------------------------------------------------------- lights


def watts_from_brightness(brightness: float) -> float:
    """Blender point-light power (W) of a `.bi` light of this brightness."""
    return float(brightness) * WATTS_PER_BRIGHTNESS


def brightness_from_watts(watts: float) -> float:
    """`.bi` brightness of a Blender light of this power (W)."""
    return float(watts) / WATTS_PER_BRIGHTNESS


# --------------------------------------------------------------------------- camera


@dataclass
class BlenderCamera:
    """The Blender camera and render settings for a `.bi` camera."""

    lens: float  # focal length, mm
    sensor_width: float  # mm
    sensor_height: float  # mm (informative: the fit is horizontal)
    sensor_fit: str  # 'HORIZONTAL'
    pixel_aspect_x: float
    pixel_aspect_y: float
    resolution_x: int
    resolution_y: int
    focus_distance: float  # distance from the camera to its target
    rotation: np.ndarray  # 3×3: columns = camera's local X, Y, Z in the world
    up_was_parallel: bool  # U was (nearly) parallel to the view: a fallback up


class BlenderLimitError(ValueError):
    """A `.bi` value Blender cannot show; `record` is the key of the record that
    holds it ('V' viewport, 'B' opening angles), so a message can name its line."""

    def __init__(self, record: str, message: str):
        self.record = record
        super().__init__(message)


def _tan_half(deg: float) -> float:
    return math.tan(math.radians(deg) / 2.0)


def lens_from_fov(fov_h_deg: float, sensor_width: float = SENSOR_WIDTH) -> tuple[float, float]:
    """(lens, sensor_width) in mm that give the horizontal opening `fov_h_deg`
    with a horizontal sensor fit; the sensor widens when the focal length would
    fall below Blender's 1 mm."""
    t = _tan_half(fov_h_deg)
    lens = (sensor_width / 2.0) / t
    if lens < MIN_LENS:
        lens, sensor_width = MIN_LENS, 2.0 * t * MIN_LENS
    return lens, sensor_width


def pixel_aspect_from_fov(
    fov_h_deg: float, fov_v_deg: float, width: int, height: int
) -> tuple[float, float]:
    """Pixel aspect (x, y), the smaller 1, that makes a `width × height` image span
    both opening angles. ValueError beyond Blender's range [1, 200]."""
    ratio = (_tan_half(fov_h_deg) * height) / (_tan_half(fov_v_deg) * width)
    if not (1.0 / MAX_PIXEL_ASPECT <= ratio <= MAX_PIXEL_ASPECT):
        raise BlenderLimitError(
            "B",
            f"opening angles {fov_h_deg:g}° × {fov_v_deg:g}° on a {width}×{height} image "
            f"need a pixel aspect of {ratio:.4g}; Blender allows 1/200 to 200",
        )
    # Exactly 1 when the angles match the image's shape up to rounding.
    if abs(ratio - 1.0) <= 1e-12:
        return 1.0, 1.0
    return (ratio, 1.0) if ratio >= 1.0 else (1.0, 1.0 / ratio)


def fov_from_blender(
    lens: float,
    sensor_width: float,
    sensor_height: float,
    sensor_fit: str,
    width: int,
    height: int,
    pixel_aspect_x: float = 1.0,
    pixel_aspect_y: float = 1.0,
) -> tuple[float, float]:
    """Opening angles (h, v) in degrees of a perspective Blender camera rendering
    `width × height` pixels, following Blender's own sensor-fit rule
    (BKE_camera_params_compute_viewplane): 'AUTO' fits `sensor_width` to the
    larger side (in pixel-aspect-corrected pixels), 'HORIZONTAL' fits
    `sensor_width` to the width, 'VERTICAL' `sensor_height` to the height."""
    ycor = pixel_aspect_y / pixel_aspect_x
    wide = width * pixel_aspect_x >= height * pixel_aspect_y
    fit = (
        sensor_fit
        if sensor_fit in ("HORIZONTAL", "VERTICAL")
        else ("HORIZONTAL" if wide else "VERTICAL")
    )
    sensor = sensor_height if sensor_fit == "VERTICAL" else sensor_width
    t = sensor / (2.0 * lens)
    if fit == "HORIZONTAL":
        tan_x, tan_y = t, t * ycor * height / width
    else:
        tan_y, tan_x = t, t * width / (ycor * height)
    return (math.degrees(2.0 * math.atan(tan_x)), math.degrees(2.0 * math.atan(tan_y)))


def look_at(position, target, up) -> tuple[np.ndarray, bool]:
    """Rotation (3×3, columns = the camera's local X, Y, Z in world space) of a
    Blender camera at `position` looking at `target` with `up` as its up hint.

    Blender cameras look along −Z with +Y up. When `up` is (nearly) parallel to the
    view, the world axis least aligned with the view is used instead and the second
    value is True."""
    position, target, up = (np.asarray(v, dtype=float) for v in (position, target, up))
    forward = target - position
    norm = np.linalg.norm(forward)
    if not norm > 0 or not np.isfinite(norm):
        raise ValueError("the camera target must differ from the camera position")
    forward = forward / norm
    z = -forward
    up_norm = np.linalg.norm(up)
    x = np.cross(up / up_norm, z) if up_norm > 0 else np.zeros(3)
    parallel = not np.linalg.norm(x) > 1e-9
    if parallel:
        hint = np.eye(3)[int(np.argmin(np.abs(forward)))]
        x = np.cross(hint, z)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z]), parallel


def camera_to_blender(camera: Camera, width: int, height: int) -> BlenderCamera:
    """Everything Blender needs for a `.bi` camera. ValueError for what Blender
    cannot show (pixel aspect beyond 200, resolution outside 4–65536)."""
    for name, size in (("width", width), ("height", height)):
        if not MIN_RESOLUTION <= size <= MAX_RESOLUTION:
            raise BlenderLimitError(
                "V",
                f"viewport {name} {size} is outside Blender's render "
                f"resolution range {MIN_RESOLUTION}–{MAX_RESOLUTION}",
            )
    fov_h, fov_v = camera.fov_deg
    lens, sensor_width = lens_from_fov(fov_h)
    pax, pay = pixel_aspect_from_fov(fov_h, fov_v, width, height)
    sensor_height = max(MIN_SENSOR, sensor_width * _tan_half(fov_v) / _tan_half(fov_h))
    rotation, parallel = look_at(camera.position, camera.target, camera.up)
    distance = float(np.linalg.norm(np.subtract(camera.target, camera.position)))
    return BlenderCamera(
        lens=lens,
        sensor_width=sensor_width,
        sensor_height=sensor_height,
        sensor_fit="HORIZONTAL",
        pixel_aspect_x=pax,
        pixel_aspect_y=pay,
        resolution_x=int(width),
        resolution_y=int(height),
        focus_distance=distance,
        rotation=rotation,
        up_was_parallel=parallel,
    )


def camera_from_blender(
    position, rotation, focus_distance: float, fov_deg: tuple[float, float]
) -> Camera:
    """A `.bi` camera from a Blender camera's world position, world rotation (3×3,
    columns local X, Y, Z; scale is removed) and focus distance (<= 0: 1 unit)."""
    rotation = np.asarray(rotation, dtype=float)
    forward = -rotation[:, 2] / np.linalg.norm(rotation[:, 2])
    up = rotation[:, 1] - forward * np.dot(rotation[:, 1], forward)
    up = up / np.linalg.norm(up)
    distance = focus_distance if focus_distance > 0 else 1.0
    position = np.asarray(position, dtype=float)
    return Camera(
        position=tuple(float(c) for c in position),
        target=tuple(float(c) for c in position + distance * forward),
        up=tuple(float(c) for c in up),
        fov_deg=(float(fov_deg[0]), float(fov_deg[1])),
    )


def same_view(camera_a: Camera, camera_b: Camera, tol: float = 1e-5) -> bool:
    """Do two `.bi` cameras give the same picture? Same position (relative to the
    target distance), same view direction and same effective up (U made
    perpendicular to the view), within `tol` (radians / relative)."""
    pa, pb = np.asarray(camera_a.position, float), np.asarray(camera_b.position, float)
    scale = max(np.linalg.norm(np.subtract(camera_a.target, pa)), 1e-30)
    if np.linalg.norm(pa - pb) > tol * scale:
        return False
    try:
        ra, _ = look_at(camera_a.position, camera_a.target, camera_a.up)
        rb, _ = look_at(camera_b.position, camera_b.target, camera_b.up)
    except ValueError:
        return False
    return bool(np.max(np.abs(ra - rb)) <= tol)


# --------------------------------------------------------------------------- materials


def principled_from_surface(surface: Surface) -> dict:
    """Principled BSDF input values (by input name) for a `.bi` surface."""
    kt, kd, ks = surface.transmission, surface.diffuse, surface.specular
    transmissive = kt > 0.0
    if transmissive:
        metallic, roughness, ior = 0.0, 0.0, surface.ior
    else:
        metallic = ks / (kd + ks) if kd + ks > 0.0 else 0.0
        roughness = min(1.0, math.sqrt(2.0 / (surface.exponent + 2.0)))
        ior = OPAQUE_IOR
    base = surface.color if not transmissive else (1.0, 1.0, 1.0)
    return {
        "Base Color": (*(float(c) for c in base), 1.0),
        "Metallic": float(metallic),
        "Roughness": float(roughness),
        "IOR": float(ior),
        "Transmission Weight": float(kt),
    }


def viewport_color(surface: Surface) -> tuple[float, float, float, float]:
    """The material's viewport display colour: the surface colour #C."""
    return (*(float(c) for c in surface.color), 1.0)


def surface_from_principled(inputs: dict, viewport=None) -> Surface:
    """A `.bi` surface from Principled BSDF input values (by input name; missing
    inputs take Blender's defaults) and the material's viewport colour (the
    colour of a transmitting sphere; Base Color when not given). The inverse of
    `principled_from_surface` where that is one-to-one; see the module's table."""
    kt = min(1.0, max(0.0, float(inputs.get("Transmission Weight", 0.0))))
    base = inputs.get("Base Color", (0.8, 0.8, 0.8, 1.0))
    color = tuple(float(c) for c in (viewport if kt > 0.0 and viewport is not None else base)[:3])
    metallic = min(1.0, max(0.0, float(inputs.get("Metallic", 0.0))))
    roughness = min(1.0, max(0.0, float(inputs.get("Roughness", 0.5))))
    ior = float(inputs.get("IOR", 1.5))
    if kt > 0.0:
        metallic, exponent, n = 0.0, GLASS_EXPONENT, ior
    else:
        exponent = min(MAX_EXPONENT, 2.0 / roughness**2 - 2.0) if roughness > 0.0 else MAX_EXPONENT
        n = 1.0
    return Surface(
        color=tuple(max(0.0, c) for c in color),
        ambient=DEFAULT_AMBIENT,
        diffuse=(1.0 - metallic) * (1.0 - kt),
        specular=metallic * (1.0 - kt),
        transmission=kt,
        exponent=max(0.0, exponent),
        ior=n,
    )


def principled_matches(a: dict, b: dict, tol: float = 1e-5) -> bool:
    """Do two sets of Principled input values agree (float32 storage allowed)?"""
    for key in set(a) & set(b):
        va, vb = np.atleast_1d(a[key]).astype(float), np.atleast_1d(b[key]).astype(float)
        if va.shape != vb.shape or np.any(np.abs(va - vb) > tol * np.maximum(1.0, np.abs(va))):
            return False
    return True


# --------------------------------------------------------------------------- stored numbers


def close(current, stored, tol: float, scale: float = 1.0) -> bool:
    """All components of `current` within `tol × max(scale, |stored|)` of `stored`."""
    c = np.atleast_1d(np.asarray(current, dtype=float))
    s = np.atleast_1d(np.asarray(stored, dtype=float))
    if c.shape != s.shape or not np.all(np.isfinite(c)) or not np.all(np.isfinite(s)):
        return False
    return bool(np.all(np.abs(c - s) <= tol * np.maximum(scale, np.abs(s))))


def prefer_stored(current, stored, tol: float = 1e-5, scale: float = 1.0):
    """The stored (file) numbers while Blender's `current` values still match them
    (Blender keeps float32, so an unchanged value differs from the file's double
    by up to ~1e-7 relative); otherwise the current ones. Tuples stay tuples."""
    if stored is None:
        return current
    try:
        if close(current, stored, tol, scale):
            return type(current)(stored) if isinstance(current, tuple) else float(stored)
    except (TypeError, ValueError):
        pass
    return current


def header_line(text: str, key: str) -> int | None:
    """Line number (1-based) of the first record with `key` in a `.bi` text (used
    to point at the 'V' or 'B' record in messages about Blender's limits)."""
    import re

    stripped = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    for number, line in enumerate(stripped.splitlines(), 1):
        tokens = line.split()
        if tokens and tokens[0] == key:
            return number
    return None
