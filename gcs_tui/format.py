"""Numbers for people: units at the edge and honest precision.

Every number a screen shows goes through here; no widget ever renders a raw float. The
rule itself — display unit chosen from σ, σ's two significant digits, ``< 1e-16`` for
p — lives in :mod:`gcs_core.display`, so that the ``gcs`` command's tables and the TUI
choose the same unit and digits for the same σ; this module re-exports it.

Nothing here imports Textual.
"""

from __future__ import annotations

from gcs_core.display import (  # noqa: F401 — the face formats through these names (one copy, in the engine)
                              DEG_FROM_SIGMA,
                              P_FLOOR,
                              bar,
                              decimals_of,
                              display_unit,
                              estimate,
                              fixed,
                              from_display,
                              nice_ticks,
                              p_text,
                              pvalue,
                              quantity,
                              scale,
                              seconds,
                              shown_unit,
                              sig,
                              span,
                              tick_labels,
                              to_display,
                              unit_column,
                              unit_label,
                              value_sigma,
                              value_text,
)
