"""The predictor's own methods by name (``[prediction] method``, :func:`~.predict.predict`).

Each :class:`PredictionMethod` says what :func:`~.predict.predict` does for it, so that the
predictor never branches on a method's name:

* ``information`` (the batch's setting): Eq 3-2 over the plan, the gyro taken as exact;
* ``kalman``: the covariance recursion of Eq 3-4 when a gyro carries a solved-for attitude
  (:mod:`.kalman`), Eq 3-2 otherwise;
* ``whole_span`` (the default fit's setting): Eq 3-2's history whose final covariance is
  the whole-span fit's, the gyro noise carried as process noise
  (:func:`~gcs_core.estimators.whole_span.uses.predicted_covariance`).

An estimator names the method that predicts its covariance
(:attr:`gcs_core.estimators.registry.Estimator.prediction`).
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_core.errors import InputError


@dataclass(frozen=True)
class PredictionMethod:
    """One way of predicting a plan's covariance.

    name : its config name (and :attr:`~.predict.PredictionResult.method`);
    gyro_recursion : Eq 3-4's recursion when a gyro carries a solved-for attitude;
    without_gyro : the method used instead when no gyro carries one;
    whole_span_final : the final covariance is the whole-span fit's;
    leaves_out_process_noise : its σ take the gyro-propagated attitude as exact; a plan
        predicted for the estimator whose method this is (the batch) is checked against
        the whole-span σ (:func:`~.predict.batch_warning`).
    """

    name: str
    gyro_recursion: bool = False
    without_gyro: str = ""
    whole_span_final: bool = False
    leaves_out_process_noise: bool = False

    def used(self, gyro_carries_attitude: bool) -> PredictionMethod:
        """The method that runs: this one, or its :attr:`without_gyro` fallback when it
        needs a gyro-carried attitude the problem lacks."""
        if self.gyro_recursion and not gyro_carries_attitude:
            return prediction_method(self.without_gyro)
        return self


#: method name -> what the predictor does for it
PREDICTION_METHODS: dict[str, PredictionMethod] = {
    m.name: m
    for m in (
        PredictionMethod("information", leaves_out_process_noise=True),
        PredictionMethod("kalman", gyro_recursion=True, without_gyro="information"),
        PredictionMethod("whole_span", whole_span_final=True),
    )
}
#: the method names, in the order the messages give them
METHODS = tuple(PREDICTION_METHODS)


def prediction_method(name: str) -> PredictionMethod:
    """The method ``name`` (one line naming ``prediction.method`` when unknown)."""
    try:
        return PREDICTION_METHODS[name]
    except KeyError:
        raise InputError(f"method must be one of {', '.join(METHODS)}, got {name!r}", key="prediction.method") from None
