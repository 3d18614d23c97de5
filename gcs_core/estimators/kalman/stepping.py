"""The stepping Kalman filter of FILTR, for the TUI and the headless batch mode.

The seed's FILTR "processes one block of data at a time" (§3.2.2): :class:`Filtr` does
the same. Each :meth:`Filtr.step` processes one block of ``block_seconds`` and returns a
:class:`BlockReport` (estimates and sigmas after the block, innovation statistics, NIS
with its χ² p-value, frames used and gated); :meth:`Filtr.run` goes to the end, smooths,
and returns a :class:`FilterResult` carrying post-fit residuals of the whole span.

* With a gyro: the multiplicative EKF of :mod:`gcs_core.estimators.kalman.mekf` (Eq 3-3, 3-4, 4-38),
  the attitude elements reinterpreted as the current attitude error δθ.
* Without a gyro (reference-pointing or spinning missions): the same blocks with Q = 0,
  i.e. recursive least squares (the seed: "a Kalman filter reduces to a recursive
  least-squares estimator when the state noise is zero").

Passes. The first pass is an EKF (re-linearized at each block start). Further passes
(``FilterOptions.max_passes``) re-linearize every block about the previous pass's
smoothed trajectory from the a priori: the iterated Kalman smoother, Gauss–Newton on
the whole span (Bell 1994). With Q = 0 it converges to the
batch least-squares solution of :func:`~gcs_core.estimators.batch.least_squares.batch_fit` (same a priori);
``tests/unit/test_kalman.py`` checks it.

Consider elements are not carried by the filter (they stay at their values, as held).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping

import numpy as np

from gcs_core.errors import EstimationError
from gcs_core.estimators.kalman.linear import solve_block
from gcs_core.estimators.kalman.mekf import (
    assemble,
    attitude_gyro_noise,
    block_epochs,
    gyro_rates,
    gyro_segment,
    make_layout,
)
from gcs_core.estimators.kalman.options import FilterOptions
from gcs_core.estimators.kalman.smoother import (
    EpochStore,
    SmoothedStates,
    block_records,
    gyro_residuals,
    rts_smooth,
    trajectory,
)
from gcs_core.estimators.residuals import make_residuals
from gcs_core.estimators.results import (
    BlockReport,
    FilterResult,
    FrameDiagnostics,
    InnovationStats,
    SmoothedTrajectory,
    nis_p_value,
    passes_text,
)
from gcs_core.frames.rotations import dcm_to_rotvec, euler123_to_dcm, quat_from_dcm, rotvec_to_dcm
from gcs_core.problem.attitude import RPY, rpy_error_jacobian
from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import linearize

log = logging.getLogger(__name__)


class Filtr:
    """Stepping Kalman filter / recursive least squares over blocks (module docstring).

    Parameters
    ----------
    problem : the calibration problem (:func:`~gcs_core.problem.build.build_problem`).
    options : :class:`FilterOptions`.
    block_seconds : length of a block [s]; each block is re-linearized at its start.
    """

    def __init__(self, problem: Problem, *, options: FilterOptions | None = None, block_seconds: float = 600.0):
        if block_seconds <= 0:
            raise EstimationError("block_seconds must be positive")
        self.options = options or FilterOptions()
        self.block_seconds = float(block_seconds)
        self._setup(problem)

    # ------------------------------------------------------------------ set-up
    def _setup(self, problem: Problem) -> None:
        self.problem = problem
        self._gyro = problem.gyro_name is not None
        self._noise = attitude_gyro_noise(problem, self.options.process_noise_scale) if self._gyro else None
        self._layout = make_layout(problem, self._noise)
        if self._layout.n == 0:
            raise EstimationError("nothing to estimate: every state element is held or consider")
        self._windows = self._make_windows()
        store = getattr(self, "_store", None)
        if store is not None:
            store.close()  # a new problem: new records
        counts = [block_epochs(problem, ta, tb, b == 0)[0].size for b, (ta, tb, _, _) in enumerate(self._windows)]
        self._offsets = np.concatenate([[0], np.cumsum(counts)]).astype(int)
        self._store: EpochStore | None = None
        self._prior()
        self.reset()

    def _make_windows(self):
        if self._gyro:
            kn = self.problem.gyro_attitude.knots
            K, bounds = kn.size - 1, [0]
            while bounds[-1] < K:
                k = int(np.searchsorted(kn, kn[bounds[-1]] + self.block_seconds - 1e-9))
                bounds.append(min(max(k, bounds[-1] + 1), K))
            return [(float(kn[a]), float(kn[b]), a, b) for a, b in zip(bounds[:-1], bounds[1:])]
        times = [sd.t for sd in self.problem.sensors if sd.n]
        if not times:
            raise EstimationError("no sensor data to filter")
        t0 = min(float(t[0]) for t in times)
        t1 = max(float(t[-1]) for t in times)
        nb = max(1, int(np.ceil((t1 - t0) / self.block_seconds - 1e-9)))
        edges = np.minimum(t0 + self.block_seconds * np.arange(nb + 1), t1)
        edges[-1] = t1
        return [(float(a), float(b), 0, 0) for a, b in zip(edges[:-1], edges[1:])]

    def _prior(self) -> None:
        """A priori values, the covariance in filter coordinates and (gyro) the attitude."""
        st, lay = self.problem.state, self._layout
        self._vals0 = st.values()
        sig = np.array([st[e].sigma0 for e in lay.elements], float)
        if np.any(~np.isfinite(sig)):
            log.warning("elements without prior information get a diffuse sigma of %g", self.options.diffuse_sigma)
            sig = np.where(np.isfinite(sig), sig, self.options.diffuse_sigma)
        P = np.diag(sig**2)
        self._C0: np.ndarray | None = None
        if self._gyro:
            att = self.problem.gyro_attitude
            rpy = [self._vals0[n] for n in RPY]
            J0 = rpy_error_jacobian(*rpy)  # δθ = J0 δ(roll, pitch, yaw)
            P[:3, :3] = J0 @ P[:3, :3] @ J0.T
            self._C0 = euler123_to_dcm(*rpy) @ att.ref.reference(att.t_ref)[0]
        self._P0 = P

    # ------------------------------------------------------------------ public API
    def reset(self) -> None:
        """Back to the a priori, before the first block of the first pass."""
        self.blocks: list[BlockReport] = []
        self._pass = 0
        self._done = False
        self._ref: dict | None = None  # the last pass's smoothed nominal
        self._prev: tuple[np.ndarray, np.ndarray] | None = None
        self._status = ""
        self._smooth: tuple[SmoothedStates, SmoothedTrajectory, np.ndarray] | None = None
        self._start_pass()

    def set_roles(self, roles: Mapping[str, str]) -> None:
        """Change element roles (``{name: "solve-for" | "consider" | "held"}``), then reset."""
        self._setup(self.problem.with_state(self.problem.state.with_roles(roles)))

    @property
    def done(self) -> bool:
        """True when every pass has processed every block."""
        return self._done

    @property
    def n_blocks(self) -> int:
        return len(self._windows)

    @property
    def pass_index(self) -> int:
        return self._pass

    @property
    def columns(self) -> tuple[str, ...]:
        """Filter state columns: ``kf.dtheta_x/y/z`` (δθ, for att.roll/pitch/yaw), then elements."""
        return self._layout.columns

    @property
    def covariance(self) -> np.ndarray:
        """(n, n) current error covariance, :attr:`columns` order, at :attr:`current_time`."""
        return self._P.copy()

    @property
    def attitude(self) -> np.ndarray | None:
        """(3, 3) current attitude estimate ``C_BI`` at :attr:`current_time` (gyro missions)."""
        return None if self._C is None else self._C.copy()

    @property
    def records_on_disk(self) -> bool:
        """True when the smoother's per-epoch records went to a temporary file."""
        return self._store is not None and self._store.spilled

    def estimate(self) -> dict[str, float]:
        """Current values of the filter's elements (attitude: roll/pitch/yaw now)."""
        x, _ = self._element_state(self.current_time)
        return dict(zip(self.problem.state.solve_for, map(float, x)))

    @property
    def current_time(self) -> float:
        """End of the last processed block (the start of the data before the first step)."""
        b = self._block - 1
        return self._windows[b][1] if b >= 0 else self._windows[0][0]

    def step(self) -> BlockReport:
        """Process the next block and return its :class:`BlockReport`."""
        if self._done:
            raise EstimationError("the filter has processed all the data; reset() to start again")
        b = self._block
        prior_x, prior_s = self._element_state(self._windows[b][0])
        frames, sol, q = self._gyro_block(b) if self._gyro else self._rls_block(b)
        report = self._report(b, frames, sol, prior_x, prior_s, q)
        self.blocks.append(report)
        self._block += 1
        if self._block == self.n_blocks:
            self._end_pass()
        return report

    def run(
        self, progress: Callable[[BlockReport], None] | None = None, cancel: Callable[[], bool] | None = None
    ) -> FilterResult:
        """Step to the end (every pass), smooth, and return the :class:`FilterResult`.

        ``progress(report)`` is called after each block; when ``cancel()`` returns True
        the run stops and the result covers the data processed so far ("cancelled").
        """
        while not self._done:
            if cancel is not None and cancel():
                return self.result(cancelled=True)
            report = self.step()
            if progress is not None:
                progress(report)
        return self.result()

    # ------------------------------------------------------------------ passes
    def _start_pass(self) -> None:
        self._block = 0
        self._vals = dict(self._vals0)
        self._C: np.ndarray | None = None if self._C0 is None else self._C0.copy()
        self._P = self._P0.copy()
        self._prev_nom = None
        self._diag = {}
        for sd in self.problem.sensors:
            m = sd.y.shape[1]
            self._diag[sd.name] = {
                "innovation": np.full((sd.n, m), np.nan),
                "S": np.full((sd.n, m, m), np.nan),
                "nis": np.full(sd.n, np.nan),
                "k_norm": np.full(sd.n, np.nan),
                "gated": np.zeros(sd.n, bool),
                "used": np.zeros(sd.n, bool),
                "valid": np.zeros(sd.n, bool),
                "epoch": np.full(sd.n, -1, int),
            }
        if self._gyro and self._store is None:
            lay = self._layout
            self._store = EpochStore(
                int(self._offsets[-1]),
                lay.d,
                lay.ns,
                lay.gs_pos.size,
                lay.nb,
                limit_bytes=self.options.memory_limit_mb * 1e6,
            )

    def _end_pass(self) -> None:
        lay = self._layout
        if self._gyro:
            assert self._store is not None and self._C0 is not None  # set up for the gyro
            s_star = np.array([self._vals[e] for e in lay.elements[lay.d :]])
            sm = rts_smooth(self._store, s_star, self._P[lay.d :, lay.d :], lay.gs_pos)
            traj = trajectory(self._store, sm, lay.nb, lay.elements[3 : lay.d])
            self._smooth = (sm, traj, s_star)
            starts = self._offsets[:-1]
            ref = {"C": traj.C_BI(starts), "bias": None if traj.bias is None else traj.bias[starts]}
            cur = np.concatenate(
                [dcm_to_rotvec(traj.C_BI(0) @ self._C0.T), traj.bias[0] if traj.bias is not None else [], s_star]
            )
            sig = np.concatenate([sm.sigma[0], np.sqrt(np.diag(self._P))[lay.d :]])
        else:
            ref = {}
            cur = np.array([self._vals[e] for e in lay.elements])
            sig = np.sqrt(np.diag(self._P))
        gated = np.concatenate([d["gated"] for d in self._diag.values()])
        converged = False
        if self._prev is not None:
            step = np.abs(cur - self._prev[0]) / np.maximum(sig, 1e-300)
            converged = bool(np.max(step) < self.options.pass_tol_sigma and np.array_equal(gated, self._prev[1]))
        self._prev = (cur, gated)
        ref["values"] = dict(self._vals)
        if converged:
            self._status = "converged"
        elif self._pass + 1 >= self.options.max_passes:
            self._status = "single_pass" if self.options.max_passes == 1 else "max_passes"
        else:
            self._ref = ref
            self._pass += 1
            self._start_pass()
            return
        self._done = True

    # ------------------------------------------------------------------ one block
    def _pre_edited(self) -> Mapping[str, np.ndarray]:
        return getattr(self.problem, "edited", None) or {}

    def _block_iterations(self) -> int:
        """Block re-linearizations are for the first (EKF) pass; later passes linearize
        every block about the same smoothed trajectory (one Gauss–Newton step)."""
        return max(self.options.block_iterations, 1) if self._ref is None else 1

    def _gates(self, frames) -> float | None | np.ndarray:
        """The innovation gate: one k for every frame, or (F,) per frame when a sensor
        has its own (``inf``: not gated)."""
        o = self.options
        if not o.edit_k_sensor:
            return o.edit_k
        k_of = [o.edit_k_sensor.get(name, o.edit_k) or np.inf for name, *_ in frames.sensors]
        return np.asarray(k_of, float)[frames.frame_sensor] if len(k_of) else np.zeros(0)

    def _rls_block(self, b: int):
        t_a, t_b, _, _ = self._windows[b]
        lay, o = self._layout, self.options
        nom = dict(self._vals) if self._ref is None else dict(self._ref["values"])
        att = [j for j, e in enumerate(lay.elements) if e.startswith("att.")]
        for it in range(self._block_iterations()):
            y0 = np.array([self._vals[e] - nom[e] for e in lay.elements])
            blk, frames = assemble(self.problem, lay, nom, None, t_a, t_b, b == 0, self._pre_edited())
            sol = solve_block(y0, self._P, blk, edit_k=self._gates(frames), group_rows=o.group_rows)
            n_it = self._block_iterations()
            if it == n_it - 1 or np.max(np.abs(sol.y[att]), initial=0.0) <= o.relinearize_rad:
                break  # near the nominal (or no more)
            for j, e in enumerate(lay.elements):  # re-linearize at the update
                nom[e] += sol.y[j]
        for j, e in enumerate(lay.elements):
            self._vals[e] = nom[e] + sol.y[j]  # x = x_nominal + y
        self._P = sol.P
        return frames, sol, None

    def _gyro_block(self, b: int):
        t_a, t_b, k_a, k_b = self._windows[b]
        lay, att, o = self._layout, self.problem.gyro_attitude, self.options
        store, noise, C = self._store, self._noise, self._C
        assert store is not None and noise is not None and C is not None  # set up for the gyro
        nom = dict(self._vals)
        if self._ref is None:  # EKF: linearize at the estimate
            C_a = C
        else:  # iterated: at the smoothed one
            C_a = self._ref["C"][b]
            nom.update({e: self._ref["values"][e] for e in lay.elements[lay.d :]})
            if lay.nb:
                nom.update(dict(zip(lay.elements[3 : lay.d], self._ref["bias"][b])))
        axes = ["xyz".index(e[-1]) for e in lay.elements[3 : lay.d]]
        for it in range(self._block_iterations()):
            y0 = np.zeros(lay.n)
            y0[:3] = dcm_to_rotvec(C @ C_a.T)  # C = exp(−[δθ×]) C_a
            y0[3:] = [self._vals[e] - nom[e] for e in lay.elements[3:]]
            omega, W, Wy, Wb = gyro_rates(att, nom, k_a, k_b)
            seg = gyro_segment(att, k_a, k_b, omega, W[:, :, lay.gyro_w], C_a, noise, Wy, Wb, axes)
            blk, frames = assemble(self.problem, lay, nom, seg, t_a, t_b, b == 0, self._pre_edited(), noise.sigma_e**2)
            sol = solve_block(y0, self._P, blk, edit_k=self._gates(frames), group_rows=o.group_rows, keep_epochs=True)
            # y is referred to the block start: its δθ estimates the start's attitude error,
            # which must be small for the linearization at the nominal to hold
            if it == self._block_iterations() - 1 or np.max(np.abs(sol.y[:3])) <= o.relinearize_rad:
                break
            C_a = rotvec_to_dcm(sol.y[:3]) @ C_a  # re-linearize at the update
            for j, e in enumerate(lay.elements[3:], start=3):
                nom[e] += sol.y[j]
        assert blk.Psi_d is not None  # a gyro block carries its transitions
        Psi = np.eye(lay.n)
        Psi[: lay.d] = blk.Psi_d[-1]
        x = Psi @ sol.y  # x = Ψ(t_b) y
        P = Psi @ sol.P @ Psi.T
        self._P = 0.5 * (P + P.T)  # symmetrize: round-off only
        self._C = rotvec_to_dcm(x[:3]) @ seg.C[-1]  # reset: nominal ⊕ δθ
        for j, e in enumerate(lay.elements[3:], start=3):
            self._vals[e] = nom[e] + x[j]
        recs, self._prev_nom = block_records(lay, blk, sol, seg, nom, C_a, self._prev_nom)
        store.write(int(self._offsets[b]), **recs)
        return frames, sol, quat_from_dcm(self._C)

    # ------------------------------------------------------------------ reporting
    def _element_state(self, t: float):
        """(x, sigma) of the solve-for elements now, in ``problem.state.solve_for`` order."""
        lay = self._layout
        x = np.array([self._vals[e] for e in lay.elements])
        P = self._P
        if self._gyro:
            rpy = self.problem.gyro_attitude.ref.rpy_from_dcm(self._C, t)
            x[:3] = rpy
            T = np.eye(lay.n)
            T[:3, :3] = np.linalg.inv(rpy_error_jacobian(*rpy))  # δ(rpy) = J⁻¹ δθ
            P = T @ P @ T.T
        perm = [lay.elements.index(n) for n in self.problem.state.solve_for]
        return x[perm], np.sqrt(np.diag(P))[perm]

    def _report(self, b, frames, sol, prior_x, prior_s, q) -> BlockReport:
        t_a, t_b, _, _ = self._windows[b]
        off = int(self._offsets[b])
        per, fd = {}, {}
        tot_nis, tot_dof, n_used, n_gated, n_invalid = 0.0, 0, 0, 0, 0
        for j, (name, idx, ep, valid) in enumerate(frames.sensors):
            dg = self._diag[name]
            dg["valid"][idx] = valid
            dg["epoch"][idx] = off + ep
            sel = np.nonzero(frames.frame_sensor == j)[0]
            fi = frames.frame_index[sel]
            m = dg["innovation"].shape[1]
            dg["innovation"][fi] = sol.nu[sel, :m]
            dg["S"][fi] = sol.S[sel, :m, :m]
            dg["nis"][fi] = sol.nis[sel]
            dg["k_norm"][fi] = sol.k_norm[sel]
            dg["gated"][fi] = sol.gated[sel]
            dg["used"][fi] = ~sol.gated[sel]
            sd = self.problem.sensor(name)
            fd[name] = FrameDiagnostics(
                name,
                sd.t[idx],
                idx,
                *(dg[k][idx] for k in ("innovation", "S", "nis", "k_norm", "gated", "used", "valid")),
            )
            used = dg["used"][idx]
            nis = float(np.sum(dg["nis"][idx][used]))
            dof = int(used.sum()) * m
            zn = dg["innovation"][idx][used] / np.sqrt(np.einsum("fii->fi", dg["S"][idx][used]))
            per[name] = InnovationStats(
                name,
                idx.size,
                int(valid.sum()),
                int(used.sum()),
                int(dg["gated"][idx].sum()),
                nis,
                dof,
                nis_p_value(nis, dof),
                float(np.sqrt(np.mean(zn**2))) if zn.size else np.nan,
            )
            tot_nis, tot_dof = tot_nis + nis, tot_dof + dof
            n_used += int(used.sum())
            n_gated += int(dg["gated"][idx].sum())
            n_invalid += int((~valid).sum())
        x, s = self._element_state(t_b)
        return BlockReport(
            b,
            self.n_blocks,
            self._pass,
            t_a,
            t_b,
            tuple(self.problem.state.solve_for),
            prior_x,
            prior_s,
            x,
            s,
            q,
            per,
            tot_nis,
            tot_dof,
            nis_p_value(tot_nis, tot_dof),
            n_used,
            n_gated,
            n_invalid,
            fd,
        )

    def frame_diagnostics(self) -> dict[str, FrameDiagnostics]:
        """Per-frame diagnostics of the current pass, whole span, every sensor."""
        out = {}
        for sd in self.problem.sensors:
            dg = self._diag[sd.name]
            out[sd.name] = FrameDiagnostics(
                sd.name,
                sd.t,
                np.arange(sd.n),
                *(dg[k] for k in ("innovation", "S", "nis", "k_norm", "gated", "used", "valid")),
            )
        return out

    def result(self, cancelled: bool = False) -> FilterResult:
        """The :class:`FilterResult` (after :meth:`run`; ``cancelled``: what was processed)."""
        if not (self._done or cancelled):
            raise EstimationError("the filter has not finished: call run() (or step() to the end)")
        lay, prob = self._layout, self.problem
        diag = self.frame_diagnostics()
        edited = {
            n: f.gated | np.asarray(self._pre_edited().get(n, np.zeros(f.t.size, bool)), bool) for n, f in diag.items()
        }
        x, P, traj = np.array([self._vals[e] for e in lay.elements]), self._P, None
        if self._gyro:
            assert self._store is not None  # set up for the gyro
            sm: SmoothedStates | None
            if self._done or (self._block == 0 and self._smooth is not None):
                assert self._smooth is not None  # every finished pass smooths
                sm, traj, s_star = self._smooth  # the last completed pass
            else:
                n_ep = int(self._offsets[self._block])
                s_star = x[lay.d :]
                sm = rts_smooth(self._store, s_star, P[lay.d :, lay.d :], lay.gs_pos, n=n_ep) if n_ep else None
                traj = trajectory(self._store, sm, lay.nb, lay.elements[3 : lay.d]) if sm is not None else None
            if traj is not None and sm is not None:
                att = prob.gyro_attitude
                rpy = att.ref.rpy_from_dcm(traj.C_BI(0), att.t_ref)
                x = np.concatenate([rpy, traj.bias[0] if traj.bias is not None else [], s_star])
                Pss = P[lay.d :, lay.d :]
                cross = sm.Gamma0 @ Pss  # cov(d_0, s) = Γ_0 P_ss
                P = np.block([[sm.P0, cross], [cross.T, Pss]])
                T = np.eye(lay.n)
                T[:3, :3] = np.linalg.inv(rpy_error_jacobian(*rpy))
                P = T @ P @ T.T
        values = dict(self._vals)
        values.update(zip(lay.elements, x))
        if self._gyro:
            epochs = {n: self._diag[n]["epoch"] for n in diag}
            residuals = gyro_residuals(prob, traj, epochs, values, edited) if traj is not None else {}
        else:
            residuals = make_residuals(prob, linearize(prob, values, lay.elements), edited)
        perm = [lay.elements.index(n) for n in prob.state.solve_for]
        used = [(f.nis[f.used], f.innovation.shape[1] * int(f.used.sum())) for f in diag.values()]
        nis, dof = float(sum(np.sum(a) for a, _ in used)), int(sum(k for _, k in used))
        status = "cancelled" if not self._done else self._status
        msg = passes_text(self._pass + 1, status)
        if prob.state.consider:
            msg += "; consider elements held at their values: " + ", ".join(prob.state.consider)
        return FilterResult(
            prob.state.with_values(values),
            tuple(prob.state.solve_for),
            x[perm],
            0.5 * (P + P.T)[np.ix_(perm, perm)],
            residuals,
            traj,
            diag,
            tuple(self.blocks),
            self._pass + 1,
            status,
            msg,
            nis,
            dof,
            nis_p_value(nis, dof),
        )
