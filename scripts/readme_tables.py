"""Rewrite the README's generated tables from the code that holds their numbers.

    python scripts/readme_tables.py           # rewrite README.md in place
    python scripts/readme_tables.py --check   # exit 1 if README.md is out of date

Each table sits between ``<!-- BEGIN <name> … -->`` and ``<!-- END <name> -->``;
only the lines between the markers are replaced. ``tiers``: the energy models
(tiers) from their registry, `core/tiers` (label, engines, accuracy figures of
reports/accuracy.md, what each trades).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.tiers import TIERS
from core.tiers.base import ENGINE_NAMES

README = ROOT / "README.md"


def _figure(x: float) -> str:
    """Two significant digits below 1 (0.50, 0.024), three above, integers from 100."""
    if x >= 100:
        return f"{x:.0f}"
    return f"{x:.3g}" if x >= 1 else f"{x:#.2g}"


def tier_table() -> str:
    rows = [
        "| tier | engines | L1 mean (worst case) | what it trades |",
        "| --- | --- | --- | --- |",
    ]
    for t in TIERS.values():
        engines = ", ".join(ENGINE_NAMES[e] for e in t.engines)
        if len(t.engines) == 1:
            engines += " only"
        a = t.accuracy
        l1 = f"{_figure(a.l1_mean)} ({_figure(a.l1_worst)})"
        if a.l1_median is not None:
            l1 += f"; median {_figure(a.l1_median)}"
        rows.append(f"| **{t.short_label}** | {engines} | {l1} | {t.trades} |")
    return "\n".join(rows)


TABLES = {"tiers": tier_table}


def update(text: str) -> str:
    """`text` with every generated table replaced (a missing marker is an error)."""
    for name, make in TABLES.items():
        pattern = re.compile(
            rf"(<!-- BEGIN {name}\b[^\n]*-->\n)(.*?)(<!-- END {name} -->)", re.DOTALL
        )
        if not pattern.search(text):
            raise ValueError(f"README has no <!-- BEGIN {name} … --> … <!-- END {name} --> block")
        text = pattern.sub(lambda m, make=make: m.group(1) + make() + "\n" + m.group(3), text)
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only check; exit 1 if out of date")
    args = ap.parse_args(argv)
    old = README.read_text(encoding="utf-8")
    new = update(old)
    if args.check:
        if new != old:
            print("README.md is out of date: run python scripts/readme_tables.py", file=sys.stderr)
            return 1
        return 0
    if new != old:
        README.write_text(new, encoding="utf-8")
        print(f"rewrote {README}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
