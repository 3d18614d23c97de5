"""FILTR for the screen: the engine's stepping filter, its block reports and a view of them.

:class:`FiltrRun` wraps :class:`gcs_core.estimators.kalman.stepping.Filtr` (one block per
:meth:`~FiltrRun.step`, several passes when the iterated smoother is on) and keeps
every :class:`~gcs_core.estimators.results.BlockReport`; :meth:`FiltrRun.view` turns them
into the plain numbers the FILTR screen draws. No Textual here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from gcs_tui.tui.derive import chi2_band


@dataclass(frozen=True)
class FiltrView:
    """What the FILTR screen shows.

    Attributes
    ----------
    done, total : blocks processed and the most a run can take (blocks × passes).
    pass_index, n_passes, block, n_blocks : where the filter is (0-based pass, 1-based block).
    t0, t1 : window of the latest block [s].
    blocks : per processed block ``(pass, block, NIS/dof, band low, band high)``.
    state : element -> (estimate, σ, unit) after the latest block.
    sensors : sensor -> (frames used, gated, NIS/dof, p) in the latest block.
    finished : every pass done; status : the run's status line once finished.
    post_fit : sensor -> post-fit normalized RMS once finished.
    """

    done: int
    total: int
    pass_index: int
    n_passes: int
    block: int
    n_blocks: int
    t0: float
    t1: float
    blocks: tuple[tuple[int, int, float, float, float], ...]
    state: Mapping[str, tuple[float, float, str]]
    sensors: Mapping[str, tuple[int, int, float, float]]
    finished: bool
    status: str
    post_fit: Mapping[str, float]

    @property
    def inside(self) -> int:
        """Blocks whose NIS lies inside their 95 % χ² band."""
        return sum(1 for _, _, z, lo, hi in self.blocks if lo <= z <= hi)


class FiltrRun:
    """A FILTR run on the workbench's current problem, every block report kept."""

    def __init__(self, wb) -> None:
        self.units = {e.name: e.unit for e in wb.analysis.problem.state}
        # the session's filter: [filter] block, k and per-sensor k as `gcs batch --method kalman`
        self.filtr = wb.analysis.make_filter()
        self.reports: list = []
        self.result = None

    @property
    def n_passes(self) -> int:
        return int(self.filtr.options.max_passes)

    @property
    def finished(self) -> bool:
        return bool(self.filtr.done)

    def step(self):
        report = self.filtr.step()
        self.reports.append(report)
        if self.filtr.done:
            self.result = self.filtr.result()
        return report

    def view(self) -> FiltrView:
        r = self.reports[-1] if self.reports else None
        blocks = []
        for b in self.reports:
            lo, hi = chi2_band(b.dof)
            dof = max(b.dof, 1)
            blocks.append((b.pass_index, b.index, b.nis / dof, lo / dof, hi / dof))
        state = (
            {}
            if r is None
            else {n: (float(x), float(s), self.units.get(n, "1")) for n, x, s in zip(r.names, r.x, r.sigma)}
        )
        sensors = (
            {}
            if r is None
            else {
                n: (st.n_used, st.n_gated, st.nis / st.dof if st.dof else math.nan, st.p_value)
                for n, st in r.sensors.items()
            }
        )
        res = self.result
        return FiltrView(
            done=len(self.reports),
            total=self.filtr.n_blocks * self.n_passes,
            pass_index=r.pass_index if r else 0,
            n_passes=self.n_passes,
            block=(r.index + 1) if r else 0,
            n_blocks=self.filtr.n_blocks,
            t0=r.t_start if r else math.nan,
            t1=r.t_end if r else math.nan,
            blocks=tuple(blocks),
            state=state,
            sensors=sensors,
            finished=self.finished,
            status=res.message if res is not None else "",
            post_fit={n: v.rms_normalized for n, v in res.residuals.items()} if res is not None else {},
        )


def advance(
    wb, blocks: int | None, progress=None, cancelled=None, on_block: Callable[[object], object] | None = None
) -> FiltrRun:
    """Process ``blocks`` FILTR blocks (None: to the end), checking ``cancelled()``
    between blocks and calling ``on_block(report)`` after each."""
    if wb.filtr is None or wb.filtr.finished:  # a finished run starts again
        wb.filtr = FiltrRun(wb)
    run = wb.filtr
    k = 0
    while not run.finished and (blocks is None or k < blocks):
        if cancelled is not None and cancelled():
            break
        report = run.step()
        k += 1
        if progress:
            progress(
                len(run.reports),
                run.filtr.n_blocks * run.n_passes,
                f"pass {report.pass_index + 1}, block {report.index + 1}/{report.n_blocks}",
            )
        if on_block:
            on_block(report)
    return run
