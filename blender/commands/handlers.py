"""Installing and removing the extension's application handlers (`bpy.app.handlers`),
shared by live update and the stale-bake check."""

from __future__ import annotations

import bpy


def _remove_ours(handlers, fn):
    # By name as well: a reloaded extension's old functions are other objects.
    for h in list(handlers):
        if h is fn or (
            getattr(h, "__module__", None) == fn.__module__ and h.__name__ == fn.__name__
        ):
            handlers.remove(h)


def install(table) -> None:
    """Append each (handler list name, function) of `table`, once (an older copy of
    the same function removed first)."""
    for name, fn in table:
        handlers = getattr(bpy.app.handlers, name)
        _remove_ours(handlers, fn)
        handlers.append(fn)


def remove(table) -> None:
    """Remove each function of `table` from its handler list."""
    for name, fn in table:
        _remove_ours(getattr(bpy.app.handlers, name), fn)
