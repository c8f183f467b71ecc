"""Make `core/tiers/fitted_table.json`: the FITTED tier's spot for every node of
a grid over x = R/D and n (see `core/tiers/fitted.py`).

    $(scripts/ensure_env.sh) bench/make_fitted_table.py      # about 1–2 minutes

One process, one core. The table is data (JSON, one row per line: small and
diffable), read once by `core.tiers.fitted.fitted_table`.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.tiers.fitted import TABLE_COLUMNS, TABLE_FILE, TABLE_N, TABLE_X
from core.tiers.spot_fit import SUN_DISTANCE, fit_spot


def table_json(columns: dict) -> str:
    """The file's text: ``X``, ``N`` and per quantity of `TABLE_COLUMNS` a row per
    x (values to 6 significant digits)."""

    def row(values):
        return json.dumps([float(f"{v:.6g}") for v in values])

    parts = [f'  "X": {row(TABLE_X)}', f'  "N": {row(TABLE_N)}']
    for k in TABLE_COLUMNS:
        rows = ",\n    ".join(row(r) for r in columns[k])
        parts.append(f'  "{k}": [\n    {rows}\n  ]')
    return "{\n" + ",\n".join(parts) + "\n}\n"


def main() -> int:
    t0 = time.time()
    cols = {k: [] for k in TABLE_COLUMNS}
    for x in TABLE_X:
        D = SUN_DISTANCE if x == 0.0 else 1.0 / x
        rows = {k: [] for k in TABLE_COLUMNS}
        for n in TABLE_N:
            fit = fit_spot(D, n)
            w, e, r, b = fit.invariants(D)
            for k, v in zip(TABLE_COLUMNS, (w, e, r, b, fit.l1), strict=True):
                rows[k].append(v)
            print(
                f"x={x:5.3f} D/R={D:9.4g} n={n:4.2f}: apex {fit.apex:9.4g} "
                f"k {fit.intensity:9.4g} H {fit.half_angle_deg:7.3f}° blend {fit.blend:.3f}  "
                f"L1 {fit.l1:.3f}",
                flush=True,
            )
        for k in TABLE_COLUMNS:
            cols[k].append(rows[k])
    TABLE_FILE.write_text(table_json(cols), encoding="utf-8")
    print(f"wrote {TABLE_FILE} in {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
