"""A material's optics as a lens: index of refraction, transmission, tint, absorption.

Pure. The Blender side (`blender/read/scene.py`) turns a material's node tree
into the plain data below (a tree of :class:`Bsdf`, :class:`Mix`, :class:`Add` for the
surface, :class:`Absorption` for the volume); :func:`evaluate_material` applies
the rules:

* **Lobes.** The surface is flattened into weighted BSDF lobes. ``Mix`` with factor
  ``f`` weighs its first shader ``1 − f`` and its second ``f`` (Blender's Mix Shader);
  ``Add`` adds both. A factor driven by a texture is not known here: the reader
  passes 0.5 and a note.
* **Transmissive lobes.** Principled BSDF: ``Transmission Weight · (1 − Metallic) ·
  Alpha`` of it refracts, with its ``IOR``; Glass BSDF and Refraction BSDF refract
  entirely. The **tint** is that of the whole path through the sphere, as Cycles
  renders it (measured in tests/blender/build/test_blender_render.py): the Principled BSDF tints
  a transmitted path by ``Base Color`` once, the Glass and Refraction BSDFs by
  ``Color`` at every surface, so ``Color²`` through a sphere. Everything else
  (Diffuse, Glossy, Emission, Transparent — which passes light straight, without
  refraction — unknown nodes, groups) refracts nothing.
* **Result.** ``transmission`` = Σ weight × refracting share (clamped to 1): the
  thesis' ``kt``; ``ior`` and ``tint`` are the averages of the refracting lobes
  weighted the same way (a note when their IORs differ); with no refracting lobe
  the material is opaque (``transmission`` 0, ``ior`` 1). ``color`` is the mean of
  all lobes' own colours (the surface colour a `.bi` file gets).
* **Volume.** Volume Absorption of density ``ρ`` and colour ``c`` absorbs
  ``σ = ρ (1 − c)`` per unit length and channel (Beer–Lambert, as Cycles); mixes
  and sums combine like the surface. Other volume nodes are ignored with a note.
"""

from __future__ import annotations

from dataclasses import dataclass, field

Color = tuple[float, float, float]

PRINCIPLED, GLASS, REFRACTION, OTHER = "PRINCIPLED", "GLASS", "REFRACTION", "OTHER"


#: The indices taken as water (Blender's preset for water is 1.333; users type 1.33):
#: open glass of such an index is a water surface (`core.scene.water`).
WATER_IOR_RANGE = (1.30, 1.36)


@dataclass(frozen=True)
class Bsdf:
    kind: str  # PRINCIPLED | GLASS | REFRACTION | OTHER
    ior: float = 1.45
    color: Color = (1.0, 1.0, 1.0)
    transmission: float = 0.0  # Principled: Transmission Weight
    metallic: float = 0.0  # Principled
    alpha: float = 1.0  # Principled
    name: str = ""  # node name, for notes
    thin_wall: bool = False  # Principled's Thin Wall (5.x): a shell, no refraction


@dataclass(frozen=True)
class Mix:
    fac: float
    first: object  # a shader tree, or None (unconnected: black)
    second: object


@dataclass(frozen=True)
class Add:
    first: object
    second: object


@dataclass(frozen=True)
class Absorption:
    density: float
    color: Color = (1.0, 1.0, 1.0)


@dataclass
class MaterialOptics:
    ior: float = 1.0
    transmission: float = 0.0  # kt: share of light refracted (0 opaque, 1 clear)
    tint: Color = (1.0, 1.0, 1.0)  # colour of a path through the sphere (entry + exit)
    absorption: Color = (0.0, 0.0, 0.0)  # σ per unit length
    color: Color = (0.8, 0.8, 0.8)  # the shaders' own colour (weighted mean), for `.bi`
    notes: list[str] = field(default_factory=list)
    #: Share of light a thin wall (Principled's Thin Wall) passes without refracting.
    thin_wall: float = 0.0

    @property
    def is_transmissive(self) -> bool:
        return self.transmission > 0.0 and self.ior > 1.0


def _clamp01(x) -> float:
    return min(max(float(x), 0.0), 1.0)


def _lobes(node, weight, out, notes):
    if node is None or weight <= 0.0:
        return
    if isinstance(node, Mix):
        f = _clamp01(node.fac)
        _lobes(node.first, weight * (1.0 - f), out, notes)
        _lobes(node.second, weight * f, out, notes)
    elif isinstance(node, Add):
        _lobes(node.first, weight, out, notes)
        _lobes(node.second, weight, out, notes)
    elif isinstance(node, Bsdf):
        out.append((weight, node))
    else:
        notes.append(f"unknown shader {node!r} treated as opaque")


def path_tint(b: Bsdf) -> Color:
    """Colour of a path through a sphere made of this lobe (see the module's rules)."""
    c = tuple(_clamp01(x) for x in b.color)
    if b.kind in (GLASS, REFRACTION):
        return tuple(x * x for x in c)
    return c


def transmitted_share(b: Bsdf) -> float:
    """Share of a lobe's light that it transmits through its surface (refracted, or
    straight through a thin wall)."""
    if b.kind in (GLASS, REFRACTION):
        return 1.0
    if b.kind == PRINCIPLED:
        return _clamp01(b.transmission) * (1.0 - _clamp01(b.metallic)) * _clamp01(b.alpha)
    return 0.0


def refracting_share(b: Bsdf) -> float:
    """Share of a lobe's light that refracts (see the module's rules): none through
    a thin wall."""
    return 0.0 if b.thin_wall else transmitted_share(b)


def evaluate_material(surface, volume=None) -> MaterialOptics:
    """The lens optics of a material given as plain data (see the module's rules)."""
    notes: list[str] = []
    lobes: list[tuple[float, Bsdf]] = []
    _lobes(surface, 1.0, lobes, notes)
    total = 0.0
    ior_sum = 0.0
    tint = [0.0, 0.0, 0.0]
    iors = set()
    thin = 0.0
    for w, b in lobes:
        if b.thin_wall:
            thin += w * transmitted_share(b)
        t = w * refracting_share(b)
        if t <= 0.0:
            continue
        total += t
        ior_sum += t * float(b.ior)
        iors.add(round(float(b.ior), 6))
        for k, c in enumerate(path_tint(b)):
            tint[k] += t * c
    optics = MaterialOptics(notes=notes, thin_wall=min(thin, 1.0))
    if thin > 0.0:
        names = ", ".join(f"'{b.name}'" for _w, b in lobes if b.thin_wall and b.name)
        notes.append(
            f"Thin Wall on{' in ' + names if names else ''}: a thin shell passes light "
            "without focusing it"
        )
    weights = sum(w for w, _ in lobes)
    if weights > 0.0:
        optics.color = tuple(
            sum(w * _clamp01(b.color[k]) for w, b in lobes) / weights for k in range(3)
        )
    if total > 0.0:
        optics.transmission = min(total, 1.0)
        optics.ior = ior_sum / total
        optics.tint = tuple(c / total for c in tint)
        if len(iors) > 1:
            notes.append(f"refracting shaders with different IORs averaged to {optics.ior:.4g}")
    optics.absorption = _absorption(volume, notes)
    return optics


def _absorption(node, notes) -> Color:
    def walk(n, w):
        if n is None or w <= 0.0:
            return (0.0, 0.0, 0.0)
        if isinstance(n, Absorption):
            d = max(float(n.density), 0.0)
            return tuple(w * d * (1.0 - _clamp01(c)) for c in n.color)
        if isinstance(n, Mix):
            f = _clamp01(n.fac)
            a, b = walk(n.first, w * (1.0 - f)), walk(n.second, w * f)
            return tuple(x + y for x, y in zip(a, b, strict=False))
        if isinstance(n, Add):
            a, b = walk(n.first, w), walk(n.second, w)
            return tuple(x + y for x, y in zip(a, b, strict=False))
        notes.append(
            f"volume {getattr(n, 'name', '') or n!r} ignored (only Volume Absorption is used)"
        )
        return (0.0, 0.0, 0.0)

    return walk(node, 1.0)


@dataclass(frozen=True)
class LensOptics:
    """What the material adds to the sphere's geometry (see `glass`)."""

    transmission_weight: float = 1.0  # w (Principled's Transmission Weight …)
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)  # colour of a path through the sphere
    absorption: tuple[float, float, float] = (0.0, 0.0, 0.0)  # σ per length (Volume Absorption)


def head_on_transmission(ior: float) -> float:
    """Fresnel transmission through both surfaces at normal incidence:
    ``T(0) = (4n/(n + 1)²)²`` (0.9216 for n = 1.5)."""
    t = 4.0 * ior / (ior + 1.0) ** 2
    return t * t
