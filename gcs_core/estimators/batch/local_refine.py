"""Exact minimization over a sensor's own non-linear parameters, between batch iterations.

A sensor's own parameters (those no other sensor and not the attitude depend on) enter
only that sensor's residuals. With the attitude held, they form a small least-squares
problem of their own, cheap to iterate: the sensor's frames alone, no attitude partials,
a handful of columns. Where those parameters enter non-linearly (a model with
``nonlinear_pairs``: the fine Sun sensor's ``A3 sin(k tan α)``, Eq 4-23), the full
Gauss–Newton iteration of Eq 3-1 crawls along a curved valley, re-linearizing every
sensor at each step to move a few parameters of one.

So, after each full step that lands near the noise floor, :func:`refine_local` first
minimizes the cost over those parameters ``z`` with everything else held at the new point
(Newton steps with the second-order terms of :mod:`gcs_core.problem.curvature`, a
Levenberg–Marquardt safeguard, the a priori). The attitude is evaluated once, without
partials, and the sensor's model then evaluates only what depends on ``z`` at the frames
in use (``ObservationModel.held``: the transfer function at the held ``tan α``). The next
full linearization starts on the floor of the valley, and its step couples ``z`` with the
attitude and the gyro again. At the solution the refinement moves nothing, so the fixed
point is that of Eq 3-1; only the path is shorter (a block Gauss–Seidel sweep inside the
Newton iteration).

References
----------
Ruhe & Wedin, "Algorithms for separable nonlinear least squares problems", SIAM Review 22
(1980) 318–337 (alternating minimization over parameter groups); Nocedal & Wright,
*Numerical Optimization*, 2nd ed., Springer 2006, §10.3.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from gcs_core.models import common
from gcs_core.models.base import ObservationModel
from gcs_core.problem import curvature
from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import iter_blocks

#: inner Newton iterations per sensor and refinement
MAX_INNER = 10
#: a full step moving no group element by more than this fraction of its σ is not refined
WORTH_SIGMA = 0.5
#: a sensor with more used frames than this is not refined (memory bound)
MAX_HELD_FRAMES = 2_000_000


def own_nonlinear(problem: Problem, names: Sequence[str]) -> dict[str, list[str]]:
    """Sensor -> its own solve-for elements that its model declares non-linear
    (``nonlinear_pairs``), for models with a held evaluation. Own: used by this sensor
    only, not by the attitude."""
    users: dict[str, int] = {}
    for pm in problem.param_map.values():
        for el in set(pm.values()):
            users[el] = users.get(el, 0) + 1
    att = set(problem.attitude.names)
    solve = set(names)
    out = {}
    for sd in problem.sensors:
        pairs = getattr(sd.model, "nonlinear_pairs", ())
        if not pairs or type(sd.model).held is ObservationModel.held:
            continue
        pm = problem.param_map[sd.name]
        local = {a for pair in pairs for a in pair}
        els = sorted(
            {pm[a] for a in local if a in pm and pm[a] in solve and users.get(pm[a]) == 1 and pm[a] not in att}
        )
        if els:
            out[sd.name] = els
    return out


def worth(step: np.ndarray, sigma: np.ndarray, names: Sequence[str], groups: Mapping[str, list[str]]) -> bool:
    """Whether a full step moves some group's elements by more than :data:`WORTH_SIGMA`
    of their σ (below that the model is linear enough in them: no refinement)."""
    index = {nm: j for j, nm in enumerate(names)}
    sel = [index[e] for els in groups.values() for e in els]
    return bool(np.any(np.abs(step[sel]) > WORTH_SIGMA * sigma[sel]))


def refine_local(
    problem: Problem,
    values: dict,
    names: Sequence[str],
    x: np.ndarray,
    x_bar: np.ndarray,
    prior_info: np.ndarray,
    edits: Mapping[str, np.ndarray],
    groups: Mapping[str, list[str]],
    tol_step_sigma: float,
) -> np.ndarray:
    """``x`` with each group's elements (:func:`own_nonlinear`) at the minimum of the cost
    with every other element held (module docstring). ``values`` (every state element) is
    a work dict, left at the returned state."""
    x = np.array(x, dtype=float)
    index = {nm: j for j, nm in enumerate(names)}
    for j, nm in enumerate(names):
        values[nm] = x[j]
    for sensor, els in groups.items():
        sd = problem.sensor(sensor)
        sel = np.array([index[e] for e in els])
        inv_map = {el: local for local, el in problem.param_map[sensor].items()}
        par = [(inv_map[e], q) for q, e in enumerate(els)]
        chunks = _held_chunks(problem, sd, values, edits)
        if not chunks:
            continue
        base = problem.params_of(sensor, values)

        def terms(z, base=base, par=par, sd=sd, chunks=chunks, sel=sel):  # this iteration's sensor, bound
            params = dict(base)
            params.update({local: z[q] for local, q in par})
            Ag, bg, chi2, Kg = _held_normal(sd, chunks, params, par)
            d = x_bar[sel] - z
            return Ag, bg, chi2 + float(np.sum(prior_info[sel] * d * d)), Kg, d

        z = x[sel].copy()
        cur = terms(z)
        lam = 0.0
        for _ in range(MAX_INNER):
            Ag, bg, cost, Kg, d = cur
            N_gn = Ag + np.diag(prior_info[sel])
            N = N_gn + Kg
            if not curvature.positive_definite(N, np.sqrt(np.diag(N_gn))):
                N = N_gn
            step = np.linalg.solve(N + lam * np.diag(np.diag(N)), bg + prior_info[sel] * d)
            if np.all(np.abs(step) <= tol_step_sigma * np.sqrt(np.diag(np.linalg.inv(N_gn)))):
                break
            trial = terms(z + step)
            if np.isfinite(trial[2]) and trial[2] <= cost:
                z, cur = z + step, trial
                lam = lam / 10.0 if lam > 1e-4 else 0.0
            else:
                lam = max(10.0 * lam, 1e-4)
        x[sel] = z
        for j, e in zip(sel, z):
            values[names[j]] = e
    return x


def _held_chunks(problem: Problem, sd, values, edits) -> list:
    """``[(y, held), ...]`` per chunk: the used frames' measurements and the model's held
    evaluation there, the attitude evaluated once (no partials)."""
    params = problem.params_of(sd.name, values)
    chunks, frames = [], 0
    for blk in iter_blocks(problem, values, (), sensors=[sd.name], exclude=edits, jacobian=False):
        if not np.any(blk.used):
            continue
        idx = None if np.all(blk.used) else np.flatnonzero(blk.used)
        y = sd.y[blk.lo : blk.hi]
        chunks.append((y if idx is None else y[idx], sd.model.held(blk.geom, params, rows=idx)))
        frames += y.shape[0] if idx is None else idx.size
        if frames > MAX_HELD_FRAMES:
            return []
    return chunks


def _held_normal(sd, chunks, params, par):
    """``(A, b, χ², K)`` of one sensor's held chunks over the elements ``par`` ((local
    name, position) pairs), from component-sparse partials
    (:class:`~gcs_core.models.base.HeldPrediction`)."""
    p = len(par)
    A, b, K = np.zeros((p, p)), np.zeros(p), np.zeros((p, p))
    chi2 = 0.0
    where = dict(par)
    wanted = set(where)
    for y, held in chunks:
        hp = held(params, wanted)
        r = y - hp.y
        nrow = r.shape[0]
        rc = [np.ascontiguousarray(r[:, c]) for c in range(r.shape[1])]
        for c in range(r.shape[1]):
            w = 1.0 / sd.sigma[c]
            qs = [(q, hp.d_par[local][1]) for local, q in par if local in hp.d_par and hp.d_par[local][0] == c]
            rows = np.empty((len(qs) + 1, nrow))
            for i, (_, v) in enumerate(qs):
                rows[i] = v
            rows[-1] = rc[c]
            rows *= w
            G = rows @ rows.T
            if qs:
                idx = np.array([q for q, _ in qs], dtype=int)
                A[np.ix_(idx, idx)] += G[:-1, :-1]
                b[idx] += G[:-1, -1]
            chi2 += float(G[-1, -1])
        curv = []
        for (a, bb), entry in hp.d2_par.items():
            if a in where and bb in where:
                c, v = common.component_values(entry, nrow)
                curv.append((where[a], where[bb], -float(rc[c] @ v) / sd.sigma[c] ** 2))
        curvature.add_block(K, np.arange(p), curv)
    return A, b, chi2, K
