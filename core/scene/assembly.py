"""A Blender scene as read for phase 1: the read's data (`BlenderSceneRead`), the
rules that turn one object's numbers into a light or a lens (`light_power`,
`lens_material`, …), and the assembly of the read from its object instances,
vectorised over them (`assemble`).

Pure (numpy only). The Blender side (`blender/read/scene.py`) walks the
depsgraph: per distinct evaluated object it makes one `InstanceGroup` (the
numbers read from Blender: a light's power, a sphere's local fit and material
optics …), per instance it notes the group, the world matrix and the instancer;
`assemble` does the rest. Objects (``orig``) and mesh sources are carried through
without being looked at.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..lens.glass import LensOptics, MaterialOptics
from ..lens.sphere_fit import BOX_RATIO, SphereFit, uniform_scales
from .arrays import SceneArrays
from .instances import Indexed, InstanceNames, LeftOut, instance_names, scale_codes, scale_reason
from .light_props import LightProps, light_power, primary_of  # noqa: F401
from .model import Camera, Light, Scene, Sphere, Surface
from .primaries import PointPrimary, PrimaryLight, SunPrimary, nominal_power, tier_primaries

#: IOR used for a lens forced with "Always" when neither the material nor the
#: override gives one.
DEFAULT_LENS_IOR = 1.5
#: `BlenderSceneRead.how` when the render depsgraph was read.
RENDER = "render"

LIGHT_GROUP, SPHERE_GROUP, OTHER_GROUP = range(3)


@dataclass
class InstanceGroup:
    """What all instances of one evaluated object / data / original share."""

    kind: int
    name: str
    orig: object
    corners: np.ndarray | None = None  # local bounding box (8 × 3)
    reason: str = ""  # OTHER_GROUP: why it is no sphere
    looks_like_lens: bool = False
    # SPHERE_GROUP
    center: np.ndarray | None = None  # local
    radius: float = 0.0
    ior: float = 1.0
    kt: float = 0.0
    lens_like: bool = False
    optics: LensOptics | None = None
    surface: Surface | None = None
    notes: list = field(default_factory=list)
    # LIGHT_GROUP
    light: LightProps | None = None
    mesh_source: object = None  # what blocks rays (`occluders`), or None


@dataclass
class BlenderSceneRead:
    arrays: SceneArrays
    width: int = 0
    height: int = 0
    camera: Camera = field(default_factory=Camera)
    sphere_sources: Sequence = field(default_factory=list)
    light_sources: list[str] = field(default_factory=list)
    left_out: list[tuple[str, str]] = field(default_factory=list)
    # For the generator (parallel to the spheres / lights):
    sphere_objects: Sequence = field(default_factory=list)  # original bpy Objects
    light_objects: list = field(default_factory=list)
    lens_optics: Sequence = field(default_factory=list)
    lens_candidates: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    material_notes: Sequence = field(default_factory=list)
    primaries: list[PrimaryLight] = field(default_factory=list)
    #: The lights as `core.scene.primaries` dataclasses (parallel to `light_sources`).
    primary_lights: list = field(default_factory=list)
    #: (light name, reason) of every light left out or only partly modelled.
    light_notes: list[tuple[str, str]] = field(default_factory=list)
    #: Names of the point lights, parallel to ``lights`` (the `.bi` model's lights).
    point_light_sources: list[str] = field(default_factory=list)
    #: (name, reason) of left-out objects that looked like lenses (refracting
    #: material or lens mode Always): the ones worth reporting to the user.
    left_out_lenses: list[tuple[str, str]] = field(default_factory=list)
    bounds: tuple[np.ndarray, np.ndarray] | None = None
    #: What blocks rays (`blender.read.occluders.Occluders`): valid while the depsgraph read is.
    occluders: object = None
    #: RENDER, or "viewport (why the render depsgraph was not read)".
    how: str = RENDER
    lights: list[Light] = field(default_factory=list)
    surfaces: Sequence = field(default_factory=list)  # `Surface` per sphere
    _scene: Scene | None = field(default=None, repr=False)

    @property
    def scene(self) -> Scene:
        """The read as an `core.scene.model.Scene` (made on first use)."""
        if self._scene is None:
            a = self.arrays
            spheres = [
                Sphere(
                    center=tuple(float(x) for x in a.center[i]),
                    radius=float(a.radius[i]),
                    surface=self.surfaces[i],
                    name=self.sphere_sources[i],
                )
                for i in range(len(a.radius))
            ]
            self._scene = Scene(
                width=self.width,
                height=self.height,
                camera=self.camera,
                lights=list(self.lights),
                objects=spheres,
            )
        return self._scene

    @property
    def scene_size(self) -> float:
        """Diagonal of everything rendered (≥ a tiny positive number)."""
        if self.bounds is None:
            return 1.0
        size = float(np.linalg.norm(self.bounds[1] - self.bounds[0]))
        return size if size > 0 and math.isfinite(size) else 1.0


@dataclass
class Blocking:
    """The instances besides the spheres that block rays (for `Occluders`)."""

    matrices: np.ndarray  # N × 4 × 4
    box_lo: np.ndarray  # N × 3, world
    box_hi: np.ndarray
    source_index: list  # per instance, into `sources`
    sources: list  # one mesh source per group


# --------------------------------------------------------------------------- one object


def render_size(resolution_x: int, resolution_y: int, percentage: int) -> tuple[int, int]:
    """The rendered image's size in pixels."""
    return resolution_x * percentage // 100, resolution_y * percentage // 100


def light_color(color, temperature_color=None) -> tuple:
    """A light's colour, × its blackbody colour when it uses a temperature."""
    c = np.array(color[:3], dtype=float)
    if temperature_color is not None:
        c = c * np.array(temperature_color[:3], dtype=float)
    return tuple(float(x) for x in c)


def box_fit_failure(extent: np.ndarray) -> SphereFit | None:
    """Why a mesh whose local bounding box has the sides `extent` cannot be a
    sphere (None: it may be one, fit it)."""
    if not np.all(np.isfinite(extent)):
        return SphereFit(False, np.zeros(3), 0.0, "not a sphere: non-finite vertex coordinates")
    if not extent.max() > 0:
        return SphereFit(False, np.zeros(3), 0.0, "zero size: all its vertices are at one point")
    if extent.min() < BOX_RATIO * extent.max():
        dims = " × ".join(f"{e:.3g}" for e in extent)
        return SphereFit(
            False, np.zeros(3), 0.0, f"not a sphere: its bounding box ({dims}) is not a cube"
        )
    return None


def lens_material(optics: MaterialOptics, mode: str, ior_override: float | None = None):
    """(ior, kt, transmission weight) of a sphere with the material `optics` and
    the lens mode `mode` (AUTO: the material decides; ALWAYS: a lens even if
    opaque, transmission 1 and IOR 1.5 unless known; NEVER: opaque); the IOR
    override (not with NEVER) replaces the IOR."""
    ior, kt = optics.ior, optics.transmission
    weight = kt
    if mode == "NEVER":
        kt = weight = 0.0
    elif mode == "ALWAYS" and not optics.is_transmissive:
        kt = weight = 1.0
        ior = DEFAULT_LENS_IOR
    if ior_override is not None and mode != "NEVER":
        ior = float(ior_override)
    return ior, kt, weight


def surface_block(optics: MaterialOptics, color) -> Surface:
    """Thesis surface block for a sphere (the Phong numbers are approximations for
    the `.bi` exporter: ka 0.1, kd 0.8(1 − kt), ks 0.2 for glass else 0.1, E 80)."""
    kt = float(optics.transmission)
    return Surface(
        color=tuple(float(c) for c in color),
        ambient=0.1,
        diffuse=round(0.8 * (1.0 - kt), 6),
        specular=0.2 if kt > 0 else 0.1,
        transmission=kt,
        exponent=80.0,
        ior=float(optics.ior) if kt > 0 else 1.0,
    )


def perspective_fov(angle_x, angle_y, angle, sensor_fit, width, height) -> tuple[float, float]:
    """(horizontal, vertical) opening in degrees of a perspective camera: its
    angles, except with the sensor fit AUTO, where `angle` spans the larger side."""
    if sensor_fit != "AUTO":
        return math.degrees(angle_x), math.degrees(angle_y)
    half_tan = math.tan(angle / 2)
    if width >= height:
        return math.degrees(angle), math.degrees(2 * math.atan(half_tan * height / width))
    return math.degrees(2 * math.atan(half_tan * width / height)), math.degrees(angle)


def camera_from_matrix(m: np.ndarray, fov=(45.0, 45.0)) -> Camera:
    """The `.bi` camera of a camera object's world matrix (it looks along −Z, +Y up)."""
    pos = m[:3, 3]
    fwd = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    up = m[:3, 1] / np.linalg.norm(m[:3, 1])
    return Camera(
        position=tuple(pos),
        target=tuple(pos + fwd * 10.0),
        up=tuple(up),
        fov_deg=(float(fov[0]), float(fov[1])),
    )


# --------------------------------------------------------------------------- all instances


def world_boxes(groups, gid, kind, M):
    """World bounding boxes (lo, hi: N × 3; NaN for lights and when no geometry
    box is finite) of the instances, from their groups' local corners."""
    n = gid.size
    corners = np.array(
        [g.corners if g.corners is not None else np.full((8, 3), np.nan) for g in groups]
    ).reshape(-1, 8, 3)
    box_lo = np.full((n, 3), np.nan)
    box_hi = np.full((n, 3), np.nan)
    geo = np.flatnonzero(kind != LIGHT_GROUP)
    if geo.size:
        w = _world_corners(corners, gid[geo], M[geo])  # N × 3 × 8
        with np.errstate(invalid="ignore"):
            finite = np.all(np.isfinite(w), axis=(1, 2))
        if finite.any():
            box_lo[geo] = w.min(axis=2)
            box_hi[geo] = w.max(axis=2)
    return box_lo, box_hi


#: Groups beyond which `_world_corners` transforms all corners in one `einsum`.
_FEW_GROUPS = 64


def _world_corners(corners, g, M):
    """The 8 corners `corners[g[n]]` through the matrices `M[n]`, as N × 3 × 8 (axis,
    corner): ``einsum("nij,nkj->nki")``, the same numbers (one 2-D einsum per group
    when the groups are few: four times faster, the same order of sums; tested)."""
    groups = np.unique(g)
    if groups.size > _FEW_GROUPS:
        w = np.einsum("nij,nkj->nki", M[:, :3, :3], corners[g]) + M[:, None, :3, 3]
        return w.transpose(0, 2, 1)
    rot = M[:, :3, :3].reshape(-1, 3)
    out = np.empty((len(g), 3, 8), dtype=np.result_type(M.dtype, corners.dtype))
    for k in groups:
        at = np.flatnonzero(g == k) if groups.size > 1 else slice(None)
        rows = rot.reshape(-1, 3, 3)[at].reshape(-1, 3)
        out[at] = np.einsum("mj,kj->mk", rows, corners[k]).reshape(-1, 3, 8)
    return out + M[:, :3, 3, None]


def _finite_rows(a: np.ndarray) -> np.ndarray:
    return np.all(np.isfinite(a), axis=1)


def add_lights(out: BlenderSceneRead, groups, gid, kind, M, names, left: LeftOut):
    """Every light into `out` as a primary (`light_read.primary_of`; few: a Python
    loop); what cannot be one is left out, what is only partly modelled gets a note
    (both in ``light_notes``). Returns their positions (a sun's NaN), nominal powers
    (`primaries.nominal_power`) and colours (lists)."""
    pos_list, power_list, color_list = [], [], []
    for i in np.flatnonzero(kind == LIGHT_GROUP):
        g = groups[gid[i]]
        name = names[i]
        primary, why, notes = primary_of(g.light, M[i], name)
        if primary is None:
            left.add(i, why, False)
            out.light_notes.append((name, why))
            continue
        out.light_notes.extend((name, note) for note in notes)
        pos = (
            np.full(3, np.nan)
            if isinstance(primary, SunPrimary)
            else np.asarray(primary.position, dtype=float)
        )
        if isinstance(primary, PointPrimary):  # the `.bi` model: point lights only
            out.lights.append(
                Light(
                    position=tuple(float(x) for x in pos),
                    color=primary.color,
                    brightness=primary.power_w,
                    radius=primary.radius,
                    name=name,
                )
            )
            out.point_light_sources.append(name)
        out.primary_lights.append(primary)
        out.primaries.extend(tier_primaries([primary]))
        out.light_sources.append(name)
        out.light_objects.append(g.orig)
        pos_list.append(pos)
        power_list.append(nominal_power(primary))
        color_list.append(primary.color)
    return pos_list, power_list, color_list


def blocking_instances(groups, gid, kind, M, box_lo, box_hi, ellipsoids) -> Blocking:
    """What blocks rays besides the spheres: every other geometry instance with a
    mesh, and the spheres that are none here (`ellipsoids`), with a finite box."""
    blocking = np.concatenate([np.flatnonzero(kind == OTHER_GROUP), ellipsoids])
    has_mesh = np.array([groups[g].mesh_source is not None for g in gid[blocking]], dtype=bool)
    blocking = blocking[has_mesh & _finite_rows(box_lo[blocking]) & _finite_rows(box_hi[blocking])]
    source_of = {g: k for k, g in enumerate(np.unique(gid[blocking]))}
    return Blocking(
        M[blocking],
        box_lo[blocking],
        box_hi[blocking],
        [source_of[g] for g in gid[blocking]],
        [groups[g].mesh_source for g in source_of],
    )


def place_spheres(groups, sg, M_sph, scale=None):
    """World centres and radii of sphere instances (groups `sg`, matrices `M_sph`,
    uniformly scaled; `scale`: their `uniform_scales` when already known)."""
    local_c = np.array(
        [g.center if g.kind == SPHERE_GROUP else np.zeros(3) for g in groups]
    ).reshape(-1, 3)
    local_r = np.array([g.radius for g in groups], dtype=float)
    scale = uniform_scales(M_sph) if scale is None else scale
    center = np.einsum("nij,nj->ni", M_sph[:, :3, :3], local_c[sg]) + M_sph[:, :3, 3]
    return center.reshape(-1, 3), local_r[sg] * scale


def _per_sphere(groups, attr, sg, dtype):
    if not sg.size:
        return np.zeros(0, dtype=dtype)
    return np.array([getattr(g, attr) for g in groups], dtype=dtype)[sg]


def assemble(
    groups: list[InstanceGroup],
    gid: np.ndarray,
    M: np.ndarray,
    pid: np.ndarray,
    parent_names: Sequence[str],
    how: str,
    width: int = 0,
    height: int = 0,
    camera: Camera | None = None,
) -> tuple[BlenderSceneRead, Blocking]:
    """The read of the instances (group `gid[i]`, world matrix `M[i]`, instancer
    `pid[i]` into `parent_names` or −1), and what blocks rays besides its spheres."""
    n = gid.size
    kind = np.array([g.kind for g in groups], dtype=np.int64)[gid] if n else np.zeros(0, np.int64)
    names: InstanceNames = instance_names([g.name for g in groups], gid, pid, parent_names)
    box_lo, box_hi = world_boxes(groups, gid, kind, M)
    out = BlenderSceneRead(
        arrays=None,
        width=width,
        height=height,
        camera=camera if camera is not None else Camera(),
        how=how,
    )
    left = LeftOut(names)
    lens_of = lambda i: groups[gid[i]].looks_like_lens  # noqa: E731

    light_pos, light_power_w, light_col = add_lights(out, groups, gid, kind, M, names, left)
    other = np.flatnonzero(kind == OTHER_GROUP)
    left.add_grouped(other, gid[other], lambda i: groups[gid[i]].reason, lens_of)

    sph = np.flatnonzero(kind == SPHERE_GROUP)
    scales = uniform_scales(M[sph])
    uniform = np.isfinite(scales)
    bad = sph[~uniform]
    blocking = blocking_instances(groups, gid, kind, M, box_lo, box_hi, bad)
    left.add_grouped(bad, scale_codes(M[bad]), lambda i: scale_reason(M[i]), lens_of)
    sph = sph[uniform]
    sg = gid[sph]
    center, radius = place_spheres(groups, sg, M[sph], scales[uniform])

    out.arrays = SceneArrays(
        light_position=np.asarray(light_pos, dtype=float).reshape(-1, 3),
        light_brightness=np.asarray(light_power_w, dtype=float),
        light_color=np.asarray(light_col, dtype=float).reshape(-1, 3),
        center=center,
        radius=radius,
        ior=_per_sphere(groups, "ior", sg, float),
        kt=_per_sphere(groups, "kt", sg, float),
    )
    out.sphere_sources = names.subset(sph)
    out.sphere_objects = Indexed([g.orig for g in groups], sg)
    out.lens_optics = Indexed([g.optics for g in groups], sg)
    out.surfaces = Indexed([g.surface for g in groups], sg)
    out.material_notes = Indexed([g.notes for g in groups], sg)
    out.lens_candidates = _per_sphere(groups, "lens_like", sg, bool)

    for name, reason, lens in left.entries():
        out.left_out.append((name, reason))
        if lens:
            out.left_out_lenses.append((name, reason))
    out.bounds = scene_bounds(box_lo, box_hi, out.arrays.light_position)
    return out, blocking


def scene_bounds(box_lo, box_hi, points):
    """(lo, hi) of the finite boxes and the `points` (None: nothing)."""
    finite = _finite_rows(box_lo) & _finite_rows(box_hi)
    points = np.reshape(points, (-1, 3))
    points = points[_finite_rows(points)]  # a sun has no position
    lo = np.concatenate([box_lo[finite], points])
    hi = np.concatenate([box_hi[finite], points])
    if not len(lo):
        return None
    return lo.min(axis=0), hi.max(axis=0)
