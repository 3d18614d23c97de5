"""The options of the stepping filter (FILTR, seed §3.2.2,
:class:`gcs_core.estimators.kalman.stepping.Filtr`); what it gives back is in
:mod:`gcs_core.estimators.results`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from gcs_core.config_schema import FilterConfig


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

    edit_k: float | None = FilterConfig.edit_k
    edit_k_sensor: Mapping[str, float | None] = field(default_factory=dict)
    process_noise_scale: float = 1.0
    max_passes: int = 3
    pass_tol_sigma: float = 1e-2
    relinearize_rad: float = 2e-4
    block_iterations: int = 4
    group_rows: int = 48
    memory_limit_mb: float = 256.0
    diffuse_sigma: float = 1e6
