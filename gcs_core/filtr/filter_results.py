"""What the stepping filter takes and gives back (FILTR, seed §3.2.2): its options, the
report of one block, the per-frame diagnostics and the result of a whole run.

Plain frozen dataclasses that the TUI's FILTR screen and the headless reports read
directly; the machine that fills them is :class:`gcs_core.filtr.stepping.Filtr`, which
re-exports them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from gcs_core.filtr.batch import SensorResiduals
from gcs_core.filtr.smoother import SmoothedTrajectory
from gcs_core.sodl.state import StateVector


@dataclass(frozen=True)
class FilterOptions:
    """Options of :class:`Filtr`.

    Attributes
    ----------
    edit_k : innovation gate: a frame with ``|ν_i|/sqrt(S_ii) > edit_k`` in any component
        is flagged and skipped (None: no gate).
    edit_k_sensor : sensor name -> its own gate (0 or None: that sensor is not gated).
    process_noise_scale : multiplies the gyro's σ_v, σ_u, σ_e (0 gives Q = 0: RLS).
    max_passes : passes over the data (1: a plain EKF; more: iterated smoother).
    pass_tol_sigma : stop iterating when no estimate moved by more than this many sigmas.
    relinearize_rad : a block whose attitude estimate ends further than this angle [rad]
        from its linearization point is run again, linearized about the estimate (an
        iterated EKF on the block; needed when the a-priori attitude is far off); at most
        ``block_iterations`` runs (first pass only).
    group_rows : scalar measurement rows per lifted group of the core (speed only).
    memory_limit_mb : smoother records above this size go to a temporary file.
    diffuse_sigma : prior 1-sigma used for elements whose ``sigma0`` is infinite.
    """

    edit_k: float | None = 5.0
    edit_k_sensor: Mapping[str, float | None] = field(default_factory=dict)
    process_noise_scale: float = 1.0
    max_passes: int = 3
    pass_tol_sigma: float = 1e-2
    relinearize_rad: float = 2e-4
    block_iterations: int = 4
    group_rows: int = 48
    memory_limit_mb: float = 256.0
    diffuse_sigma: float = 1e6


@dataclass(frozen=True)
class FrameDiagnostics:
    """Per-frame filter diagnostics of one sensor (m measurement components).

    Attributes
    ----------
    name : sensor; t : (N,) frame times; index : (N,) frame numbers in the sensor's data.
    innovation : (N, m) ``ν = y − h(x⁻)``, telemetry units (NaN where not processed).
    S : (N, m, m) innovation covariance ``H P⁻ Hᵀ + R``.
    nis : (N,) ``νᵀ S⁻¹ ν``; k_norm : (N,) Frobenius norm of the gain K (mixed units).
    gated : (N,) refused by the k-σ gate (flagged and skipped, never dropped silently).
    used : (N,) updated the state; valid : (N,) the model is defined there.
    """

    name: str
    t: np.ndarray
    index: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    k_norm: np.ndarray
    gated: np.ndarray
    used: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True)
class InnovationStats:
    """Innovation statistics of one sensor over one block.

    Attributes
    ----------
    n_frames, n_valid, n_used, n_gated : frame counts.
    nis : Σ NIS over used frames; dof : Σ m over used frames; p_value : ``P(χ²_dof ≥ nis)``.
    rms_normalized : RMS of ``ν_i / sqrt(S_ii)`` over used frames (1.0 when consistent).
    """

    name: str
    n_frames: int
    n_valid: int
    n_used: int
    n_gated: int
    nis: float
    dof: int
    p_value: float
    rms_normalized: float


@dataclass(frozen=True)
class BlockReport:
    """What one :meth:`Filtr.step` did.

    Attributes
    ----------
    index : block number in the pass; n_blocks : blocks per pass; pass_index : 0-based.
    t_start, t_end : the block's time window [s].
    names : solve-for element names (``problem.state.solve_for`` order).
    prior_x, prior_sigma : (n,) estimates and 1-sigma at the block start;
    x, sigma : (n,) after the block. With a gyro, ``att.roll/pitch/yaw`` are those of the
        *current* attitude (at ``t_start`` / ``t_end``) relative to the reference frame.
    q_BI : (4,) attitude at ``t_end`` (gyro missions) or None.
    sensors : sensor -> :class:`InnovationStats`.
    nis, dof, p_value : block totals over used frames.
    frames_used, frames_gated, frames_invalid : counts over all sensors.
    frames : sensor -> :class:`FrameDiagnostics` of this block's frames.
    """

    index: int
    n_blocks: int
    pass_index: int
    t_start: float
    t_end: float
    names: tuple[str, ...]
    prior_x: np.ndarray
    prior_sigma: np.ndarray
    x: np.ndarray
    sigma: np.ndarray
    q_BI: np.ndarray | None
    sensors: Mapping[str, InnovationStats]
    nis: float
    dof: int
    p_value: float
    frames_used: int
    frames_gated: int
    frames_invalid: int
    frames: Mapping[str, FrameDiagnostics] = field(repr=False, default_factory=dict)

    @property
    def fraction(self) -> float:
        """Progress within the pass, 0..1."""
        return (self.index + 1) / self.n_blocks


@dataclass(frozen=True)
class FilterResult:
    """Outcome of a filter run, with its diagnostics.

    Attributes
    ----------
    state : the state with estimated values (attitude: roll/pitch/yaw at the reference
        time, from the smoothed attitude, as :class:`~gcs_core.filtr.batch.BatchResult`).
    solve_for : element names; x : (n,) estimates; P : (n, n) covariance (same order).
    residuals : sensor -> post-fit :class:`~gcs_core.filtr.batch.SensorResiduals`.
    trajectory : smoothed attitude at every epoch (gyro missions) or None.
    frames : sensor -> :class:`FrameDiagnostics` of the last pass.
    blocks : every :class:`BlockReport` of every pass.
    passes : passes made; status : "converged", "max_passes", "single_pass" or "cancelled".
    nis, dof, p_value : innovation totals of the last pass.
    """

    state: StateVector
    solve_for: tuple[str, ...]
    x: np.ndarray
    P: np.ndarray
    residuals: dict[str, SensorResiduals]
    trajectory: SmoothedTrajectory | None
    frames: Mapping[str, FrameDiagnostics]
    blocks: tuple[BlockReport, ...]
    passes: int
    status: str
    message: str
    nis: float
    dof: int
    p_value: float

    @property
    def sigma(self) -> dict[str, float]:
        return {n: float(np.sqrt(self.P[i, i])) for i, n in enumerate(self.solve_for)}

    @property
    def values(self) -> dict[str, float]:
        return self.state.values()
