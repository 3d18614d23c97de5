"""VERIF on a fitted analysis: the mission's onboard attitudes against the ground fit (§4.4).

The onboard attitude history is the mission's ``onboard_attitude.csv`` (ICD §6,
columns ``t, q1..q4``); the ground attitude is the fitted problem's attitude at the
same times, with its 1-σ from the fit covariance (:mod:`gcs_core.verif.ground`); the
requirement is the config's ``[verification] requirement_deg``.
"""

from __future__ import annotations

import numpy as np

from gcs_core.errors import InputError
from gcs_core.units import DEG
from gcs_core.verif.compare import TREND_WINDOW_S, VerifResult, verify
from gcs_core.verif.ground import covered, ground_attitude


def verify_analysis(
    analysis, *, angles: str = "euler", window_s: float = TREND_WINDOW_S, requirement_rad: float | None = None
) -> VerifResult:
    """Verify the onboard attitudes of ``analysis.mission`` against its fit.

    Parameters
    ----------
    analysis : a :class:`gcs_core.session.Analysis` (fitted here if it has no result).
    angles : ``"euler"`` or ``"body"`` (:func:`gcs_core.verif.compare.verify`).
    window_s : trend window [s].
    requirement_rad : overrides the config's ``requirement_deg``.
    """
    ob = analysis.mission.onboard
    if ob is None or len(ob) == 0:
        raise InputError(
            "the mission has no onboard attitude to verify (onboard_attitude.csv, ICD §6)",
            file=analysis.mission.spec.root / "mission.toml",
            key="onboard_attitude.file",
        )
    if analysis.result is None:
        analysis.fit(holdout=False)
    t_ob = np.asarray(ob.t, dtype=float)
    q_ob = np.column_stack([ob.columns[c] for c in ("q1", "q2", "q3", "q4")])
    keep = covered(analysis, t_ob)
    if not np.any(keep):
        raise InputError("no onboard attitude falls inside the fitted span", key="onboard_attitude.file")
    g = ground_attitude(analysis, t_ob[keep])
    sigma = g.sigma_rpy if angles == "euler" else g.sigma_body
    req = analysis.config.verification.requirement_deg * DEG if requirement_rad is None else requirement_rad
    A_of = dict(zip(g.t.tolist(), g.A))
    return verify(
        t_ob[keep],
        q_ob[keep],
        g.t,
        g.q,
        sigma,
        requirement_rad=req,
        mode=analysis.mission.spec.attitude_mode,
        reference=lambda t: np.stack([A_of[x] for x in np.asarray(t).tolist()]),
        angles=angles,
        window_s=window_s,
    )
