"""The whole-span fit's knots (and the gyro's read-out errors) as nuisance columns of the
score tests of candidate effects (:mod:`gcs_core.diagnosis.ranking`).

At the fit's solution, each candidate's partials are formed at the corrected attitude (the
knots' chained attitude, :func:`.knots.chained_attitude`) and what the knot corrections
absorb is projected out: their rows are accumulated per knot alongside the state's and the
candidates' (:class:`.knots.KnotSystem`, streaming), the read-out error of each epoch is
eliminated as the fit eliminated it (:class:`.readout.ReadoutEpochs`, about the fit's ε̂),
and :meth:`KnotElimination.eliminate` reduces the normal equations over ``[x c]`` by the
knots. The static counterpart is :class:`gcs_core.estimators.static_algebra.NoElimination`.
"""

from __future__ import annotations

import numpy as np

from gcs_core.estimators.whole_span.knots import KnotSystem, chained_attitude
from gcs_core.estimators.whole_span.passes import Dynamics
from gcs_core.estimators.whole_span.readout import ReadoutEpochs
from gcs_core.problem.build import Problem


class KnotElimination:
    """The knots of ``dyn`` eliminated from normal equations over ``K`` columns.

    ``A``, ``g`` are the caller's accumulators (the read-out elimination adds its terms to
    them as the epochs close). Per block: :meth:`visit` when a sensor's blocks begin,
    :meth:`add` with the block's weighted rows, :meth:`passed` when its frames are done;
    :meth:`finish` after the last block, then :meth:`eliminate`.
    """

    def __init__(self, problem: Problem, dyn: Dynamics, K: int, A: np.ndarray, g: np.ndarray):
        self.dyn = dyn
        self.knots = KnotSystem(dyn.grid, K, dyn.R, dyn.z, stream=True, keep=False)
        self.knots.track(problem.sensors)
        self.readout = ReadoutEpochs(dyn.sig_e2, A, g, self.knots, problem.sensors, dyn.errors) if dyn.sig_e2 else None
        #: linearize the candidates about the corrected attitude (and the fit's ε̂)
        self.problem = dyn.problem(problem, readout=True)

    def visit(self, sd) -> None:
        if self.readout is not None:
            self.readout.visit(sd)

    def add(self, blk, Hm: np.ndarray, rw: np.ndarray, c: np.ndarray) -> None:
        """A block's weighted rows ``Hm`` (rows, columns ``c``) and residuals ``rw``."""
        D = getattr(blk.pred, "d_att", None)
        if D is None or blk.geom.C_BI is None:
            return
        sd, dyn = blk.sensor, self.dyn
        t_blk = sd.t[blk.lo : blk.hi]
        C = np.ascontiguousarray(chained_attitude(blk.geom.C_BI, dyn.grid, dyn.z, dyn.R, t_blk))
        w = blk.used[:, None] / sd.sigma[None, :]
        Hr = np.column_stack((Hm, rw))
        self.knots.add_rows(D, C, w, t_blk, Hr, c)
        if self.readout is not None:
            self.readout.add(t_blk, D, w, C, Hr, c)

    def passed(self, sd, hi: int) -> None:
        if self.readout is not None:
            self.readout.passed(sd, hi)
        else:
            self.knots.passed(sd, hi)

    def finish(self) -> None:
        if self.readout is not None:
            self.readout.finish()

    def eliminate(self, N: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``N``, ``g`` over ``[x c]`` with the knots eliminated together: what they absorb
        is projected out of the state and the candidates alike."""
        N_red, g_red, _ = self.knots.eliminate(N, g)
        return N_red, g_red
