"""The generate report: its text and its figures, from a `planning.Work` (pure).

Skipped pairs are counted by their reason's code (`skip_reasons`): phase 1's from
its skip table, planning's from `Plan.skipped`, the pre-selection's from the
budget.
"""

from __future__ import annotations

import traceback

import numpy as np

from ..phase1.point_lights import Phase1Result, SkipTable
from ..phase1.skip_reasons import Reason, reason_kind, reason_text
from ..shared.words import share_text

#: How many skipped pairs / left-out objects a report names.
REPORT_FIRST = 3


def skip_report(work):
    """(skipped count, first few "light × lens: reason", counts per reason)."""
    read, result, sel, plan = work.read, work.result, work.selection, work.plan
    s = result.skip_table
    cand = read.lens_candidates[s.lens] if len(s) else np.zeros(0, dtype=bool)
    first, counts = [], {}
    a = read.arrays
    for k in np.flatnonzero(cand)[:REPORT_FIRST]:
        i = int(s.lens[k])
        details = dict(
            radius=float(a.radius[i]), ior=float(a.ior[i]), kt=float(a.kt[i]), other=int(s.other[k])
        )
        first.append(
            f"{read.light_sources[int(s.light[k])]} × {read.sphere_sources[i]}: "
            + reason_text(int(s.code[k]), details)
        )
    if cand.any():
        sub = SkipTable(s.light[cand], s.lens[cand], s.code[cand], s.other[cand])
        counts.update(Phase1Result(result.table, sub, a).skip_counts())
    for pair in plan.skipped:
        light, lens, why = pair
        if len(first) < REPORT_FIRST:
            first.append(f"{light} × {lens}: {why}")
        counts[pair.kind] = counts.get(pair.kind, 0) + 1
    if sel.budget.over_cap:
        kind = reason_kind(Reason.NOT_AMONG_STRONGEST, dict(count=sel.preselect))
        counts[kind] = sel.budget.over_cap
    total = sum(counts.values())
    return total, first, counts


def plural(n, word, many=None):
    return f"{n} {word if n == 1 else (many or word + 's')}"


def made_text(lights: int, layers: int = 0, fallback: int = 0, on=(), fallback_on=()) -> str:
    """What a run made, each thing by its name: "1 lens light", "2 caustic layers on
    Table, Wall", "1 caustic layer on Table and 1 fallback spot on glossy or
    transparent Mirror", "0 lens lights". `layers`: the layer meshes (one
    per receiver plane their caustics land on), `on` the receivers they lie on;
    `fallback`: the layer tier's Fitted spots, `fallback_on` the receivers they light."""
    parts = []
    if layers:
        parts.append(plural(layers, "caustic layer") + (f" on {_names(on)}" if on else ""))
    if fallback:
        parts.append(
            f"{plural(fallback, 'fallback spot')} on glossy or transparent "
            + (_names(fallback_on) if fallback_on else "receivers")
        )
    if lights or not parts:
        parts.append(plural(lights, "lens light"))
    return " and ".join(parts)


def kept_text(made, kept, word: str = "lens light") -> str:
    """The lenses with lens lights of the user's (copies, renamed or moved ones, kept
    by Generate and Clear) beside the ones made now: `made` and `kept` are (name,
    lens) pairs. "Marble has 2 lens lights: 'Lens light Lamp > Marble' (made now) and
    'My copy' (yours, kept)" (the user's by name); the first `REPORT_FIRST` lenses,
    then a count; "" when nothing is kept. `word`: what they are ("caustic layer":
    its lens is the receiver it lies on)."""
    by_lens: dict = {lens: [] for _, lens in kept}
    if not by_lens:
        return ""
    for name, lens in made:
        if lens in by_lens:
            by_lens[lens].append(f"'{name}' (made now)")
    for name, lens in sorted(kept):
        by_lens[lens].append(f"'{name}' (yours, kept)")
    parts = []
    for lens in sorted(by_lens)[:REPORT_FIRST]:
        names = by_lens[lens]
        listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        parts.append(f"{lens or 'no lens'} has {plural(len(names), word)}: {listed}")
    more = len(by_lens) - REPORT_FIRST
    if more > 0:
        parts.append(f"and {plural(more, 'more lens', 'more lenses')} with {word}s of yours")
    return "; ".join(parts)


def thousands(n: int) -> str:
    """An integer with thin spaces between its thousands: "1 240", "20 000"."""
    return f"{int(n):,}".replace(",", "\u2009")


def mesh_lenses_text(lit, unlit=()) -> str:
    """The glass meshes traced as lenses: `lit` (name, triangles) of those whose
    caustic layers were made, `unlit` names of those no light reaches ("" for none):
    "caustic layers for 2 glass objects (Rod: 1 240 triangles, Lens: 2 000 triangles)"."""
    parts = []
    if lit:
        shown = ", ".join(f"{n}: {thousands(t)} triangles" for n, t in lit[:REPORT_FIRST])
        more = len(lit) - REPORT_FIRST
        shown += f", and {more} more" if more > 0 else ""
        parts.append(f"caustic layers for {plural(len(lit), 'glass object')} ({shown})")
    if unlit:
        names = ", ".join(list(unlit)[:REPORT_FIRST])
        more = len(unlit) - REPORT_FIRST
        names += f" and {more} more" if more > 0 else ""
        parts.append(f"no light reaches the glass of {names}")
    return "; ".join(parts)


def left_out_text(left_out_lenses) -> str:
    """The objects that look like lenses but are none, with why ("" for none)."""
    if not left_out_lenses:
        return ""
    shown = "; ".join(f"{n} ({why})" for n, why in left_out_lenses[:REPORT_FIRST])
    more = len(left_out_lenses) - REPORT_FIRST
    return (
        f"left out {plural(len(left_out_lenses), 'object')} (Lens Lights models solid glass "
        f"spheres and closed glass meshes): {shown}" + (f"; and {more} more" if more > 0 else "")
    )


def report_message(
    work,
    made: int,
    *,
    layers: int = 0,
    fallback: int = 0,
    on=(),
    fallback_on=(),
    read_as_rendered: bool = True,
) -> tuple[str, str, dict]:
    """(level, message, figures) of a run that made `made` lens lights, `layers`
    caustic layers on the receivers `on` and `fallback` fallback spots lighting
    `fallback_on` (`made_text`); `read_as_rendered`: False when the scene was read
    as the viewport shows it (`work.read.how` says why)."""
    read, result, sel, plan = work.read, work.result, work.selection, work.plan
    lights = len(read.light_sources)
    # the glass meshes traced as lenses count beside the spheres
    lenses = int(np.count_nonzero(read.lens_candidates)) + len(getattr(read, "mesh_lenses", []))
    # and the water surfaces (issue 26: `work.water`, set by Generate's water stage)
    lenses += len(getattr(getattr(work, "water", None), "waters", None) or [])
    skipped, first, counts = skip_report(work)
    # Flux without a light: every source's estimated flux minus the built lights'.
    rows = {id(src): t for t, src in enumerate(sel.sources)}
    built = sum(
        float(sel.flux_kept[rows[id(p.source)]]) for p in plan.lights if id(p.source) in rows
    )
    left_share = (1.0 - built / sel.flux_total) if sel.flux_total > 0 else 0.0
    any_made = made or layers or fallback
    left_share = (
        min(max(left_share, 0.0), 1.0) if any_made else (1.0 if sel.flux_total > 0 else 0.0)
    )

    level = "INFO"
    parts = [
        f"Created {made_text(made, layers, fallback, on, fallback_on)} ({plural(lights, 'light')}"
        f" × {plural(lenses, 'lens', 'lenses')})"
    ]
    if not lights:
        level = "WARNING"
        parts.append("no light with power is enabled for rendering")
    elif lenses == 0:
        level = "WARNING"
        parts.append("no glass sphere found")
    if skipped:
        text = f"skipped {plural(skipped, 'pair')}: " + "; ".join(first)
        if skipped > len(first):
            text += f"; and {skipped - len(first)} more"
        parts.append(text)
        if len(counts) > 1 or skipped > len(first):
            parts.append(
                "by reason: "
                + ", ".join(
                    f"{n} {kind}" for kind, n in sorted(counts.items(), key=lambda kv: -kv[1])
                )
            )
    if sel.budget.merged:
        parts.append(f"merged {plural(sel.budget.merged, 'source')} into nearby lens lights")
    share = share_text(left_share, 1.0) if len(result.table) else ""
    if share:
        what = "is in no caustic layer or lens light" if layers else "has no lens light"
        parts.append(f"{share} of the lenses' flux {what}")
    if read.left_out_lenses:
        parts.append(left_out_text(read.left_out_lenses))
    notes = getattr(read, "light_notes", [])
    if notes:
        shown = "; ".join(f"{n}: {why}" for n, why in notes[:REPORT_FIRST])
        more = len(notes) - REPORT_FIRST
        parts.append("not modelled: " + shown + (f"; and {more} more" if more > 0 else ""))
    if not read_as_rendered:
        parts.append(f"scene read as the {read.how}")
    figures = dict(
        created=made,
        layers=layers,
        fallback=fallback,
        sources=len(result.table),
        skipped=skipped,
        skipped_by_reason=counts,
        merged=sel.budget.merged,
        primaries=lights,
        lenses=lenses,
        left_out=len(read.left_out_lenses),
        light_notes=list(getattr(read, "light_notes", [])),
        flux_left_out=left_share,
        how=read.how,
    )
    return level, "; ".join(parts), figures


def linking_note(version: tuple, engine: str, inside: int) -> str:
    """The warning for lens lights inside their lens (`BlenderLight.inside_lens`)
    where light and shadow linking do not work: EEVEE before Blender 4.3."""
    if inside and engine.startswith("BLENDER_EEVEE") and tuple(version[:2]) < (4, 3):
        return (
            f"{plural(inside, 'lens light')} inside {'its' if inside == 1 else 'their'} "
            "lens: EEVEE before Blender 4.3 ignores light and shadow linking, so the lens "
            "shadows them (render in Cycles or Blender 4.3+)"
        )
    return ""


def _names(names, first=5) -> str:
    names = list(names)
    more = f" and {len(names) - first} more" if len(names) > first else ""
    return ", ".join(names[:first]) + more


def linking_groups_note(ungrouped, conflicts, blender_says=(), user_sets=0) -> str:
    """The warning when lens lights could not be linked exactly within Blender's
    limits (63 light sets and 64 linking collections per scene, less the user's own):
    `ungrouped` lens names whose lights are not excluded from their lens (its glass
    then shadows them), `conflicts` (light, lens) pairs whose lens shares the light's
    group though its beam reaches it (that lens neither receives nor blocks the
    light), `blender_says` Blender's own console lines about its limits."""
    parts = []
    if ungrouped:
        parts.append(
            f"{plural(len(ungrouped), 'lens', 'lenses')} ({_names(ungrouped)}): "
            "lens lights not excluded from their lens, Blender's light-linking sets are "
            f"used up{f' ({user_sets} by your own linking)' if user_sets else ''}: the "
            "lens can shadow them"
        )
    if conflicts:
        pairs = [f"{light} → {lens}" for light, lens in conflicts]
        parts.append(
            f"{plural(len(conflicts), 'lens light')} share a linking group with a lens "
            f"their beam reaches ({_names(pairs, 3)}): that lens neither receives nor "
            "blocks them (Blender's 63 light-linking sets are too few to keep them apart)"
        )
    for line in blender_says:
        parts.append(f"Blender says: {line}")
    return "; ".join(parts)


def error_text(stage, exc):
    """'Lens Lights could not <stage>: <error> (<file>:<line>)'."""
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    at = f" ({where.filename.rsplit('/', 1)[-1]}:{where.lineno})" if where else ""
    return f"Lens Lights could not {stage}: {type(exc).__name__}: {exc}{at}"
