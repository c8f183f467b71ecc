"""Live update's caustic layer between two full bakes: the last full layer's rasters
kept (same texel lines, so the Blender meshes keep their topology and positions: only
the irradiance is written), each (light, lens) pair's beam traced on a coarse grid and
splatted alone into them (`rasters.beam_fluxes`), and remembered by its inputs: a
pair whose light, lens and blockers are those of the last update is not traced
again, its texels are reused. The layer drawn is their sum (`rasters.fixed_layer`).

This is the *coarse* layer shown while the user drags or plays (fewer rays, fewer
samples of an extended light, fewer sub-cells, the full layer's rasters): the full
one (`pipeline.bake`, what Generate makes) follows when they stop. The receivers, the
pairs (by name) and the glass meshes' beams are not followed here: any change there
needs the full bake (`LiveLayer.coarse` returns None).
"""

from __future__ import annotations

import hashlib
import pickle
from dataclasses import dataclass, field

import numpy as np

from .beam_trace import trace_beams
from .pipeline import SheetBake, SheetSource
from .rasters import beam_fluxes, fixed_layer, fixed_rasters
from .smooth import drawn_geometry, drawn_irradiance

#: The coarse beams: (rings, azimuths, samples of an extended light at most) per
#: source, the finest of these whose cells, over all sources, stay within
#: `COARSE_CELLS` (the first for many sources); sub-cells per side of a landed cell
#: at most. 10 marbles × 2 lights: 8 × 32 × 4, 274 000 sub-cells against the full
#: layer's 4.3 million; one marble × 2 lights: 12 × 48 × 4 (16 × 64 × 4: L1 against
#: the full layer 0.18 instead of 0.22, but 26 ms of CPU instead of 16 per changed
#: pair; bench/live_update.py).
COARSE_GRIDS = ((8, 32, 4), (12, 48, 4), (16, 64, 4), (16, 64, 8), (16, 64, 16))
COARSE_CELLS = 5_000
COARSE_SUBDIVISION = 4
#: Binomial passes over the coarse rasters' texel flux (`rasters.blur_flux`): a coarse
#: splat's sampling noise smoothed (L1 against the full layer 0.35 → 0.13 at 2).
COARSE_BLUR = 2


def coarse_grid(n_sources: int) -> tuple[int, int, int]:
    """The coarse beam's (rings, azimuths, samples) for ``n_sources`` sources
    (`COARSE_GRIDS`)."""
    fits = [g for g in COARSE_GRIDS if g[0] * g[1] * g[2] * max(n_sources, 1) <= COARSE_CELLS]
    return fits[-1] if fits else COARSE_GRIDS[0]


def source_key(source: SheetSource) -> bytes:
    """A digest of everything a source's beam is traced from (emitter, lens, samples,
    its own mesh among the receivers, blockers): equal keys, equal beams."""
    # (a pickle holds every field, arrays by their bytes: equal inputs, equal bytes;
    # 5× faster than walking the fields)
    h = hashlib.blake2b(pickle.dumps(source, protocol=pickle.HIGHEST_PROTOCOL), digest_size=16)
    return h.digest()


@dataclass
class LiveLayer:
    """The rasters of the last full bake (``bake``) of ``names`` ((light, lens) per
    source), and per source the coarse beam's texels remembered by its input key."""

    bake: SheetBake
    names: list
    receivers_key: bytes
    # (light, lens) → (input key, `rasters.BeamFlux`, flux leaving the lens)
    entries: dict = field(default_factory=dict)
    traced: int = 0  # beams traced since it was made (the tests count them)
    reused: int = 0

    def __post_init__(self):
        index = self.bake.index
        self.rasters = fixed_rasters(self.bake.layer.patches, len(self.names), len(index.patches))
        self._weights = None

    def drawn(self, layer) -> list[np.ndarray]:
        """Per patch of ``layer`` (a `coarse` one: the full bake's rasters), its
        irradiance at the drawn mesh's vertices (`smooth.drawn_irradiance`; the
        rasters' geometry weighed once)."""
        if self._weights is None:
            self._weighed()
        return [drawn_irradiance(p, w) for p, w in zip(layer.patches, self._weights, strict=True)]

    def anchors(self) -> list[np.ndarray]:
        """Per patch, the first and last vertex of its drawn mesh (2, 3): a mesh that
        holds them is this layer's (not one an undo brought back)."""
        if self._weights is None:
            self._weighed()
        return self._anchors

    def _weighed(self):
        drawn = [drawn_geometry(p) for p in self.bake.layer.patches]
        self._weights = [d[3] for d in drawn]
        self._anchors = [d[0][[0, -1]] for d in drawn]

    def coarse(self, sources: list[SheetSource], names: list, receivers_key: bytes):
        """The coarse layer of ``sources`` (named ``names``) in the full bake's rasters,
        tracing only the sources whose inputs changed; None when the full bake is
        needed (other pairs, other receivers, a glass mesh's beam)."""
        old = {name: k for k, name in enumerate(self.names)}
        if len(old) != len(self.names) or set(names) != set(old) or len(names) != len(old):
            return None  # other pairs: other rasters
        if receivers_key != self.receivers_key or any(s.lens.kind != "ball" for s in sources):
            return None
        was = [old[name] for name in names]  # each source's beam in the rasters
        nr, na, samples = coarse_grid(len(sources))
        grid = repr((nr, na, samples)).encode()
        keys = [source_key(s) + grid for s in sources]
        stale = [i for i, k in enumerate(keys) if self.entries.get(names[i], (None,))[0] != k]
        self.reused += len(sources) - len(stale)
        groups: dict[int, list[int]] = {}
        for i in stale:
            groups.setdefault(min(sources[i].n_source, samples), []).append(i)
        for k, ids in groups.items():
            beams = trace_beams(
                [(sources[i].emitter, sources[i].lens) for i in ids],
                nr,
                na,
                k,
                [sources[i].blockers for i in ids],
            )
            own = [sources[i].own_object for i in ids]
            fluxes = beam_fluxes(
                beams,
                [was[i] for i in ids],
                self.bake.index,
                self.rasters,
                own if any(o >= 0 for o in own) else None,
                max_subdivision=COARSE_SUBDIVISION,
            )
            for i, b, f in zip(ids, beams, fluxes, strict=True):
                self.entries[names[i]] = (keys[i], f, b.total_flux)
            self.traced += len(ids)
        ordered = [self.entries[name] for name in names]
        layer = fixed_layer(
            self.rasters, [f for _, f, _ in ordered], sum(e for _, _, e in ordered), COARSE_BLUR
        )
        now = np.argsort(was)  # the rasters' sources in this update's order
        for pl in layer.patches:
            pl.sources = now[np.asarray(pl.sources, dtype=np.int64)]
        return layer
