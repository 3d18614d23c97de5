"""The estimators by name, as ``[analysis] method`` names them (ICD §6), behind one interface.

Each :class:`Estimator` fits a :class:`~gcs_core.problem.build.Problem` and returns a
:class:`~gcs_core.estimators.results.FitResult`; what else a caller needs of the method
(the fit that trains the held-out span, the computed warnings about what the method leaves
out, the provenance of the attitude it writes) is an attribute here, so that the session,
the diagnosis and the reports never branch on the method's name. The result carries its own
algebra (:mod:`gcs_core.estimators.results`).

* ``whole_span`` (the default): least squares over the whole span with the gyro's process
  noise as knot corrections (:mod:`gcs_core.estimators.whole_span.fit`);
* ``batch``: least squares with the gyro taken as exact (Eq 3-1, 3-2,
  :mod:`gcs_core.estimators.batch.least_squares`);
* ``kalman``: the MEKF and its smoother, block by block (Eq 3-3, 3-4,
  :mod:`gcs_core.estimators.kalman.stepping`).

Adding an estimator: a subpackage with its fit and its result (a dataclass that satisfies
``FitResult``, with :class:`~gcs_core.estimators.results.StaticAlgebra` or its own algebra),
an :class:`Estimator` entry in :data:`ESTIMATORS`, and its name in the config's methods
(:data:`gcs_core.config_schema.METHODS`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Protocol

from gcs_core.errors import EstimationError
from gcs_core.estimators.batch.least_squares import BatchOptions, batch_fit
from gcs_core.estimators.kalman.options import FilterOptions
from gcs_core.estimators.kalman.stepping import Filtr
from gcs_core.estimators.results import FitResult
from gcs_core.estimators.whole_span.fit import whole_span_fit
from gcs_core.estimators.whole_span.uses import batch_wander_cost
from gcs_core.problem.build import Problem


@dataclass(frozen=True)
class FitSettings:
    """What every estimator may read of the analysis config: the least-squares options, the
    filter's options and its block length [s]."""

    batch: BatchOptions
    filter: FilterOptions
    block_seconds: float


class Estimator(Protocol):
    """One estimation method.

    name : its config name; training : the name of the estimator that fits the training span
    of the held-out test (its own, or a cheaper one with the same model); attitude_source :
    what the ground attitude it writes is called in the attitude history (ASF ``source``);
    prediction : the predictor's method for its covariance without data.
    """

    @property
    def name(self) -> str: ...

    @property
    def training(self) -> str: ...

    @property
    def attitude_source(self) -> str: ...

    @property
    def prediction(self) -> str:
        """The predictor's method that forms this estimator's covariance without data
        (:data:`gcs_core.predictor.methods.PREDICTION_METHODS`)."""
        ...

    @property
    def gyro_process_noise(self) -> bool:
        """Whether a gyro-carried attitude wanders under the gyro's noise in this estimator
        (False: it holds the propagated attitude exact, so the wander shows in every sensor
        as a slow dependence that score tests cannot tell from a drift)."""
        ...

    def fit(
        self,
        problem: Problem,
        settings: FitSettings,
        *,
        initial: Mapping[str, float] | None = None,
        previous: FitResult | None = None,
        edited: Mapping | None = None,
        start: FitResult | None = None,
        progress: Callable | None = None,
        cancel: Callable | None = None,
    ) -> FitResult:
        """Fit ``problem``: warm-started at ``initial`` values or a ``start`` solution,
        refitting from a ``previous`` one after a change of state, with the frames
        ``edited`` held out."""
        ...

    def warnings(self, problem: Problem, result: FitResult) -> list[str]:
        """Honesty warnings about what the method leaves out, computed on these data."""
        ...

    def bias_elements(self, line_mid, line_slope, walk_ref, book_slope, t_ref: float, t_mid: float):
        """What this estimator's static gyro bias elements (``bias`` at ``t_mid``,
        ``bias_rate``) are of a true bias history: ``line_mid``, ``line_slope`` its
        least-squares line over the span, ``walk_ref`` its value at ``t_ref``, ``book_slope``
        the data book's drift (Monte Carlo's truth, :mod:`gcs_core.trade.montecarlo`)."""
        ...


def _warm(initial, start) -> dict:
    return {"initial": initial} if start is None else {"start": start}


@dataclass(frozen=True)
class BatchEstimator:
    """Batch least squares (Eq 3-1, 3-2): the gyro-carried attitude taken as exact."""

    name: str = "batch"
    gyro_process_noise: bool = False
    training: str = "batch"
    attitude_source: str = "batch"
    prediction: str = "information"

    def fit(
        self, problem, settings, *, initial=None, previous=None, edited=None, start=None, progress=None, cancel=None
    ):
        kw = {"edited": edited} if edited is not None else {}
        return batch_fit(problem, settings.batch, initial=initial if start is None else start.state.values(), **kw)

    def warnings(self, problem: Problem, result: FitResult) -> list[str]:
        """The batch treats the gyro-propagated attitude as exact between its parameters.
        When the data book gives the gyro noise, what that costs on these data is computed
        (:func:`~gcs_core.estimators.whole_span.uses.batch_wander_cost`): the batch's
        understatement of σ and its expected error from the wander, in its own σ, from the
        reduced normal matrices with and without the process noise, and the χ² the wander
        leaves in the residuals."""
        if problem.gyro_name is None:
            return []
        cost = batch_wander_cost(problem, result)
        if cost is None or cost["worst_bias_sigma"] < 0.5:
            return []
        worst = ", ".join(f"{k} ×{v:.2f}" for k, v in cost["sigma_ratio"][:4])
        return [
            f"batch method: the gyro noise (not modelled by the batch) makes its σ too small "
            f"(σ with the process noise / batch σ: {worst}); the expected error of those "
            f"elements from the wander reaches {cost['worst_bias_sigma']:.1f} batch σ, and the "
            f"wander leaves Δχ² = {cost['delta_chi2']:.1f} in the residuals. Use method = "
            '"whole_span" (the default) for honest σ and p-values.'
        ]

    def bias_elements(self, line_mid, line_slope, walk_ref, book_slope, t_ref: float, t_mid: float):
        """The batch's bias and drift are the least-squares line through the span."""
        return line_mid, line_slope


@dataclass(frozen=True)
class WholeSpanEstimator:
    """Least squares over the whole span with the gyro's process noise (the default)."""

    name: str = "whole_span"
    gyro_process_noise: bool = True
    training: str = "whole_span"
    attitude_source: str = "batch"
    prediction: str = "whole_span"

    def fit(
        self, problem, settings, *, initial=None, previous=None, edited=None, start=None, progress=None, cancel=None
    ):
        kw: dict = _warm(initial, start)
        if previous is not None:
            kw["previous"] = previous
        if edited is not None:
            kw["edited"] = edited
        return whole_span_fit(problem, settings.batch, **kw)

    def warnings(self, problem: Problem, result: FitResult) -> list[str]:
        return []

    def bias_elements(self, line_mid, line_slope, walk_ref, book_slope, t_ref: float, t_mid: float):
        """The whole-span fit's bias is ``b(t) = bias + bias_rate (t − t_mid) + β(t)`` with
        ``β(t_ref) = 0`` (knots.py: ``z_0 = 0``): its static bias is the walk at ``t_ref``
        carried to ``t_mid`` by the deterministic drift (the data book's), and ``bias_rate``
        is that drift; the walk after ``t_ref`` is the knots' β."""
        return walk_ref + book_slope * (t_mid - t_ref), book_slope


@dataclass(frozen=True)
class KalmanEstimator:
    """The MEKF and its smoother (Eq 3-3, 3-4); its held-out span is trained by the batch
    (the same model, and a filter pass per training fit would double the cost)."""

    name: str = "kalman"
    gyro_process_noise: bool = True
    training: str = "batch"
    attitude_source: str = "filter"
    prediction: str = "kalman"

    def fit(
        self, problem, settings, *, initial=None, previous=None, edited=None, start=None, progress=None, cancel=None
    ):
        fr = self.make_filter(problem, settings).run(progress=progress, cancel=cancel)
        return replace(fr, message=f"Kalman filter + smoother: {fr.message}")

    @staticmethod
    def make_filter(problem: Problem, settings: FitSettings) -> Filtr:
        """A stepping FILTR machine on ``problem`` (the TUI steps it block by block)."""
        return Filtr(problem, options=settings.filter, block_seconds=settings.block_seconds)

    def warnings(self, problem: Problem, result: FitResult) -> list[str]:
        return []

    def bias_elements(self, line_mid, line_slope, walk_ref, book_slope, t_ref: float, t_mid: float):
        """The smoother's bias element is the random walk at ``t_ref``, less the drift line."""
        return walk_ref - line_slope * (t_ref - t_mid), line_slope


#: method name -> estimator
ESTIMATORS: dict[str, Estimator] = {e.name: e for e in (WholeSpanEstimator(), BatchEstimator(), KalmanEstimator())}


def estimator(name: str) -> Estimator:
    """The estimator a config's ``method`` names."""
    try:
        return ESTIMATORS[name]
    except KeyError:
        raise EstimationError(f"unknown method {name!r} (one of {', '.join(ESTIMATORS)})") from None
