"""Ranking candidate effects by the χ² each would remove — without refitting.

At the converged solution of the current state ``x`` (normal matrix ``N = P̄⁻¹ +
H_xᵀ W H_x``, ``W = R⁻¹``) a candidate effect ``c`` with partials ``H_c`` would, if added
and the fit repeated, remove (to first order, exactly for a linear model)::

    g_c  = H_cᵀ W r                                    (score: gradient of ½χ² at c = 0)
    S_cc = H_cᵀ W H_c − H_cᵀ W H_x N⁻¹ H_xᵀ W H_c       (information of c given x)
    Δχ²  = g_cᵀ S_cc⁻¹ g_c                             (Rao score statistic)

Under the null hypothesis (the effect is absent and the noise model is right) Δχ² is
χ²-distributed with ``dof = rank(S_cc)`` degrees of freedom, which gives the p-value.
This is the local (score) form of the likelihood-ratio test, and the detection step of
the Baarda–Teunissen DIA procedure. One linearization with every candidate's columns
costs about two batch iterations (the candidates' columns widen ``Hᵀ W H``;
``benchmarks/ranking_vs_refit.py``); no candidate is refitted.

Minimal detectable bias (Baarda): for a 1-dof candidate, the smallest value detected
with probability γ at level α is ``|c| = sqrt(λ₀ / S_cc)``, ``λ₀`` the non-centrality
giving power γ (λ₀ ≈ 17.07 for α = 0.001, γ = 0.8).

Identifiability:

* against the state — the fraction of the candidate's signature the state can absorb,
  ``1 − λ_min(S_cc) / λ_min(H_cᵀ W H_c)`` (after scaling); near 1 means the data cannot
  tell the effect from the elements already estimated, which are named from the
  regression ``B = N⁻¹ H_xᵀ W H_c``;
* against other candidates — the largest canonical correlation of their conditional
  signatures; above ``alias_tol`` the two cannot be told apart and both say so.

References
----------
Rao, C. R., "Large sample tests of statistical hypotheses...", Proc. Camb. Phil. Soc. 44,
1948 (score test). Baarda, W., *A testing procedure for use in geodetic networks*,
Netherlands Geodetic Commission 2(5), 1968. Teunissen, P. J. G., *Testing theory: an
introduction*, Delft 2000, ch. 4 (DIA, minimal detectable bias).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from scipy import stats

from gcs_core.diagnosis.catalogue import Effect
from gcs_core.estimators.results import FitResult
from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import iter_blocks, window_geometry
from gcs_core.problem.prepare import geometry_variants

#: canonical correlation above which two candidates are called indistinguishable
ALIAS_TOL = 0.98
#: share of a candidate's signature the state may absorb before it is unidentifiable
ABSORB_TOL = 0.999


@dataclass(frozen=True)
class Candidate:
    """One effect not in the state, scored at the current solution.

    Attributes
    ----------
    effect : the catalogue entry.
    delta_chi2 : χ² the effect would remove; dof : its degrees of freedom.
    p_value : P(χ²_dof ≥ delta_chi2); p_adjusted : Bonferroni over all candidates.
    estimate : name -> predicted value of each element if added (one Gauss–Newton step).
    sigma : name -> its predicted 1-sigma.
    mdb : name -> minimal detectable bias of each element (α, power 0.8).
    absorbed : share of the signature the current state can absorb (0..1).
    aliases_state : elements the signature aliases with.
    aliases_candidates : (candidate id, canonical correlation) pairs above ALIAS_TOL.
    identifiable : not absorbed by the state and not aliased with a stronger candidate.
    significant : ``p_adjusted`` below the family-wise level α it was ranked at.
    sensors : sensor -> Δχ² share seen in that sensor's residuals.
    explanation : a paragraph for the analyst.
    """

    effect: Effect
    delta_chi2: float
    dof: int
    p_value: float
    p_adjusted: float
    estimate: Mapping[str, float]
    sigma: Mapping[str, float]
    mdb: Mapping[str, float]
    absorbed: float
    aliases_state: tuple[str, ...]
    aliases_candidates: tuple[tuple[str, float], ...]
    identifiable: bool
    sensors: Mapping[str, float] = field(default_factory=dict)
    explanation: str = ""
    significant: bool = False

    @property
    def id(self) -> str:
        return self.effect.id

    @property
    def passes(self) -> bool:
        """The verdict: identifiable and significant (``p_adjusted < α``), so discovery may
        add it."""
        return self.identifiable and self.significant

    def as_report(self) -> dict:
        return {
            "id": self.id,
            "sensor": self.effect.sensor or "model",
            "effect": self.effect.effect,
            "delta_chi2": round(self.delta_chi2, 3),
            "dof": self.dof,
            "p_value": self.p_value,
            "p_adjusted": self.p_adjusted,
            "identifiable": self.identifiable,
            "absorbed_by_state": round(self.absorbed, 4),
            "aliases": list(self.aliases_state) + [a for a, _ in self.aliases_candidates],
            "estimate": dict(self.estimate),
            "sigma": dict(self.sigma),
            "explanation": self.explanation,
        }


@lru_cache(maxsize=64)
def mdb_noncentrality(alpha: float, power: float = 0.8, dof: int = 1) -> float:
    """λ₀ with P(χ²_dof(λ₀) > χ²_{dof,1−α}) = power (Baarda's non-centrality). A root search
    of a few milliseconds, cached: every ranking of a session asks for the same λ₀."""
    from scipy.optimize import brentq

    crit = stats.chi2.isf(alpha, dof)
    return float(brentq(lambda lam: stats.ncx2.sf(crit, dof, lam) - power, 1e-6, 1e4))


def _variants(problem: Problem, sd) -> dict:
    """Geometry variants of a sensor, computed once per problem (they do not depend on
    the state, and the field-model variant costs a full IGRF evaluation). They hold only
    the reference vectors that change (O(N) per variant, for the sensors a physics
    candidate concerns)."""
    cache = problem.__dict__.setdefault("_variant_cache", {})
    if sd.name not in cache:
        cache[sd.name] = geometry_variants(sd, problem.builder, problem.tables[sd.name])
    return cache[sd.name]


def _physics_block(problem: Problem, blk, values, phys_ids: Sequence[str]) -> list[tuple[int, np.ndarray]]:
    """For the physics candidates concerning this block's sensor: (candidate position,
    prediction change (n, m) when the option flips on, zero where undefined)."""
    sd = blk.sensor
    variants = _variants(problem, sd)
    out = []
    for j, eid in enumerate(phys_ids):
        geom_alt = variants.get(eid)
        if geom_alt is None:
            continue
        g1 = window_geometry(geom_alt, blk.lo, blk.hi, sd.n)
        g1 = replace(g1, C_BI=blk.geom.C_BI, omega_B=blk.geom.omega_B, spin_axis_I=blk.geom.spin_axis_I)
        y1 = sd.model.predict(g1, problem.params_of(sd.name, values)).y
        d = sd.model.residual(y1, blk.y_pred, g1)  # wrapped where the observable wraps
        out.append((j, np.where(np.isfinite(d), d, 0.0)))
    return out


def rank_candidates(
    problem: Problem,
    result: FitResult,
    effects: Sequence[Effect],
    *,
    alpha: float = 0.001,
    edited: Mapping[str, np.ndarray] | None = None,
    exclude_frames: Mapping[str, np.ndarray] | None = None,
    chunk: int | None = None,
    smoothed: bool = False,
) -> list[Candidate]:
    """Score every candidate effect (module docstring); most significant first.

    ``effects`` are the candidates (effects not in the state); physics effects must be
    ones whose option is currently off. One streaming pass over the data (chunks of
    ``chunk`` frames, default the problem's) accumulates the information of the state
    and every candidate together; memory does not grow with the span.

    ``smoothed``: the score ``g`` is formed from the result's own post-fit residuals (the
    Kalman smoother's, at the smoothed attitude) rather than from the deterministic
    gyro-carried linearization. The smoother has removed the attitude wander of the gyro
    noise, which the Q = 0 residuals would otherwise offer as a signature (a time offset
    correlates with it); the information ``S`` stays that of the deterministic model,
    which makes the test conservative for wander-like signatures and exact otherwise.
    """
    state = result.state
    values = state.values()
    x_names = list(result.solve_for)
    n = len(x_names)
    sensor_effects = [e for e in effects if not e.physics]
    c_names: list[str] = []
    for e in sensor_effects:
        c_names += [nm for nm in e.elements if nm not in c_names]
    phys = [e for e in effects if e.physics]
    phys_ids = [e.id for e in phys]
    cols = x_names + c_names
    k_all = len(c_names) + len(phys)
    K = n + k_all
    exclude = _excluded(problem, result, exclude_frames)
    # accumulate over used frames: A = [H_x H_c]ᵀ W [H_x H_c], g = [.]ᵀ W r
    A = np.zeros((K, K))
    g = np.zeros(K)
    per_sensor_g: dict[str, np.ndarray] = {}
    work: dict = {}  # chunk buffers, reused from chunk to chunk
    # nuisance columns the fit carries besides the state (a whole-span fit's knots and
    # read-out errors): the candidates are linearized as the fit was, and what those absorb
    # is taken out (the result's own algebra, FitResult.candidate_elimination)
    elim = result.candidate_elimination(problem, K, A, g)
    src = elim.problem
    for blk in iter_blocks(src, values, cols, exclude=exclude, weighted=True, chunk=chunk, work=work):
        if not np.any(blk.used):
            continue
        sd = blk.sensor
        elim.visit(sd)
        H, c = blk.H, blk.cols
        assert H is not None  # rows stored (not gram-only blocks)
        extra = _physics_block(problem, blk, values, phys_ids) if phys_ids else []
        if extra:
            w = blk.used[:, None] / sd.sigma[None, :]
            H = np.concatenate([H, np.stack([d * w for _, d in extra], -1)], axis=2)
            c = np.concatenate([c, [n + len(c_names) + j for j, _ in extra]])
        Hm = H.reshape(-1, c.size)
        rw = blk.weighted_residual()
        if smoothed and sd.name in result.residuals:
            rr = result.residuals[sd.name].residual[blk.lo : blk.hi]
            rw = (np.where(blk.used[:, None], np.nan_to_num(rr), 0.0) / sd.sigma).reshape(-1)
        A[np.ix_(c, c)] += Hm.T @ Hm
        gs = Hm.T @ rw
        elim.add(blk, Hm, rw, c)
        elim.passed(sd, blk.hi)
        g[c] += gs
        acc = per_sensor_g.setdefault(sd.name, np.zeros(K))
        acc[c] += gs
    elim.finish()
    s0 = np.array([state[nm].sigma0 for nm in x_names])
    prior = np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0)
    Nxx = A[:n, :n] + np.diag(prior)
    # the state's gradient at the solution is ~0 (converged); include it for honesty:
    # the score of c given x re-optimized is g_c − A_cx N⁻¹ g_x'
    gx = g[:n] + prior * (
        np.array([state[nm].value for nm in x_names]) - np.array([result.state[nm].value for nm in x_names])
    )
    # the nuisance columns eliminated from [x c] together: what they absorb is projected out
    N_all = A.copy()
    N_all[:n, :n] = Nxx
    N_red, g_red = elim.eliminate(N_all, np.concatenate([gx, g[n:]]))
    Nxx, Axc, A_c = N_red[:n, :n], N_red[:n, n:], N_red[n:, n:]
    gx, g_c = g_red[:n], g_red[n:]
    B = np.linalg.solve(Nxx, np.column_stack([Axc, gx]))
    Bc, bx = B[:, :-1], B[:, -1]
    S_all = A_c - Axc.T @ Bc  # conditional information, all candidates
    g_all = g_c - Axc.T @ bx
    idx_of: dict[str, list[int]] = {}
    for e in sensor_effects:
        idx_of[e.id] = [c_names.index(nm) for nm in e.elements]
    for j, e in enumerate(phys):
        idx_of[e.id] = [len(c_names) + j]
    lam0 = mdb_noncentrality(alpha, 0.8, 1)
    raw = []
    A_cc = A[n:, n:]
    x_scale = np.sqrt(np.diag(A[:n, :n]))[:, None]
    for e in effects:
        ix = idx_of[e.id]
        S = S_all[np.ix_(ix, ix)]
        Acc = A_cc[np.ix_(ix, ix)]
        gc = g_all[ix]
        dchi, dof, est, sig, absorbed = _score(S, Acc, gc)
        # aliases with the state: largest regression weights of the candidate's signature
        weights = np.abs(Bc[:, ix]) * x_scale
        wsum = weights.sum(axis=1)
        order = np.argsort(-wsum)
        total = wsum.sum() or 1.0
        aliases = tuple(x_names[i] for i in order[:4] if wsum[i] / total > 0.15) if absorbed > 0.5 else ()
        names = list(e.elements) if e.elements else [e.id]
        sigma = {nm: float(sig[i]) for i, nm in enumerate(names)}
        mdb = {nm: float(np.sqrt(lam0 / S[i, i])) if S[i, i] > 0 else float("inf") for i, nm in enumerate(names)}
        shares = {}
        for sname, gs in per_sensor_g.items():
            gsc = gs[n:][ix]
            if np.any(gsc):
                shares[sname] = float(np.abs(gsc @ (est if est.size else gsc)))
        raw.append([e, dchi, dof, est, sigma, mdb, absorbed, aliases, shares])
    return _verdicts(raw, effects, idx_of, S_all, result, alpha)


def _excluded(problem: Problem, result: FitResult, exclude_frames) -> dict[str, np.ndarray]:
    """Sensor -> frames left out of the scores: those the fit edited, and ``exclude_frames``."""
    exclude: dict[str, np.ndarray] = {}
    for sd in problem.sensors:
        ex = np.zeros(sd.n, bool)
        res = result.residuals.get(sd.name)
        if res is not None:
            ex |= res.edited
        if exclude_frames and sd.name in exclude_frames:
            ex |= exclude_frames[sd.name]
        exclude[sd.name] = ex
    return exclude


def _verdicts(raw, effects, idx_of, S_all, result: FitResult, alpha: float) -> list[Candidate]:
    """The ranked candidates from their scores ``raw``: p-values adjusted for the number of
    candidates (Bonferroni), aliases between candidates, and whether each is identifiable;
    most significant first, each with its explanation."""
    # Bonferroni within each group: the catalogue's effects, and the generic drift families
    # the residual-structure search offered (docs/residual_structure.md, family-wise honesty)
    n_family = sum(1 for r in raw if is_family(r[0]))
    m_of = {True: max(n_family, 1), False: max(len(raw) - n_family, 1)}
    n_meas = sum(int(np.count_nonzero(r.used)) * r.residual.shape[1] for r in result.residuals.values())
    log_n = float(np.log(max(n_meas, 2)))
    # aliasing between candidates (canonical correlation of conditional signatures). The
    # pairs are O(k²), and at short spans their algebra cost as much as the pass over the
    # data: each candidate's information is pseudo-inverted once, a bound on every pair's
    # ρ² comes from one product, and only pairs that may pass ALIAS_TOL are computed.
    pinvs = [_pinv(S_all[np.ix_(idx_of[e.id], idx_of[e.id])]) for e in effects]
    may_alias = _alias_bound(S_all, [idx_of[e.id] for e in effects], pinvs) >= ALIAS_TOL**2 - 1e-3
    out = []
    for ia, item in enumerate(raw):
        e, dchi, dof, est, sigma, mdb, absorbed, aliases, shares = item
        p = float(stats.chi2.sf(dchi, dof)) if dof > 0 else 1.0
        cand_alias = []
        for ib, other in enumerate(raw):
            oe = other[0]
            if oe.id == e.id or not may_alias[ia, ib]:
                continue
            rho = _canonical_corr(S_all, idx_of[e.id], idx_of[oe.id], pinvs[ia], pinvs[ib])
            if rho > ALIAS_TOL:
                cand_alias.append((oe.id, rho, other[1], other[2]))
        # an alias "wins" when it explains the data better after a BIC penalty per dof
        # (a drift family does not make a catalogue effect of the same signature unidentifiable:
        # the known physics keeps precedence, docs/residual_structure.md)
        stronger = [
            a
            for a in cand_alias
            if (a[2] - a[3] * log_n) > (dchi - dof * log_n) + 1e-9 and (is_family(e) or "_vs_" not in a[0])
        ]
        identifiable = dof > 0 and absorbed < ABSORB_TOL and not stronger
        tot = sum(shares.values()) or 1.0
        out.append(
            Candidate(
                e,
                dchi,
                dof,
                p,
                min(1.0, p * m_of[is_family(e)]),
                {k: v for k, v in est_items(e, est, result)},
                sigma,
                mdb,
                absorbed,
                aliases,
                tuple((a[0], a[1]) for a in cand_alias),
                identifiable,
                {k: v / tot for k, v in shares.items()},
                significant=min(1.0, p * m_of[is_family(e)]) < alpha,
            )
        )
    out.sort(key=lambda c: (c.p_value, -c.delta_chi2))
    return [replace(c, explanation=explain(c, alpha)) for c in out]


def is_family(e: Effect) -> bool:
    """A generic drift family (``<effect>_vs_<channel>``, :mod:`gcs_core.models.drift`)."""
    return "_vs_" in e.effect


def est_items(e: Effect, est: np.ndarray, result: FitResult):
    names = list(e.elements) if e.elements else [e.id]
    for i, nm in enumerate(names):
        base = result.state[nm].value if nm in result.state else 0.0
        yield nm, float(base + est[i]) if i < est.size else float("nan")


def _score(S: np.ndarray, Acc: np.ndarray, gc: np.ndarray):
    """Δχ², dof, step, sigma and absorbed share for one candidate (pseudo-inverse on rank)."""
    k = S.shape[0]
    d = np.sqrt(np.clip(np.diag(Acc), 0, None))
    sc = np.where(d > 0, d, 1.0)
    Ss = S / np.outer(sc, sc)
    Ss = 0.5 * (Ss + Ss.T)
    w, V = np.linalg.eigh(Ss)
    keep = w > 1e-9 * max(1.0, float(np.max(np.diag(Acc / np.outer(sc, sc))) if k else 1.0))
    if not np.any(keep) or np.all(d == 0):
        return 0.0, 0, np.zeros(k), np.full(k, np.inf), 1.0
    gs = gc / sc
    proj = V[:, keep].T @ gs
    dchi = float(np.sum(proj**2 / w[keep]))
    step = (V[:, keep] @ (proj / w[keep])) / sc
    cov = (V[:, keep] / w[keep]) @ V[:, keep].T / np.outer(sc, sc)
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    sig = np.where(np.isin(np.arange(k), np.nonzero(np.abs(V[:, keep]).sum(axis=1) > 0)[0]), sig, np.inf)
    Accs = Acc / np.outer(sc, sc)
    w_full = np.linalg.eigvalsh(0.5 * (Accs + Accs.T))
    absorbed = float(1.0 - max(w[0], 0.0) / max(w_full[0], 1e-300)) if w_full[0] > 1e-12 else 1.0
    absorbed = min(max(absorbed, 0.0), 1.0)
    return dchi, int(np.count_nonzero(keep)), step, sig, absorbed


def _pinv(S: np.ndarray) -> np.ndarray | None:
    """Pseudo-inverse of one candidate's conditional information (None if it fails)."""
    try:
        return np.linalg.pinv(S, rcond=1e-10, hermitian=True)
    except np.linalg.LinAlgError:
        return None


def _alias_bound(S_all: np.ndarray, ixs: Sequence[Sequence[int]], pinvs: Sequence[np.ndarray | None]) -> np.ndarray:
    """(E, E) upper bounds of every candidate pair's squared canonical correlation.

    ``M_ab = S_aa⁺ S_ab S_bb⁺ S_ba`` is similar to a positive semi-definite matrix, so its
    eigenvalues (the squared canonical correlations) are ≥ 0 and ``ρ²_ab ≤ tr M_ab``.
    With ``P_ab = S_aa⁺ S_ab`` (the rows of every candidate stacked: one product),
    ``tr M_ab = Σ P_ab ∘ P_baᵀ``, a block sum. Accurate to rounding, which callers allow
    for; a failed pseudo-inverse (None) gives 0 (no alias, as in :func:`_canonical_corr`).
    """
    flat = np.array([i for ix in ixs for i in ix], dtype=int)
    member = np.zeros((flat.size, len(ixs)))  # stacked row -> its candidate
    blocks = []
    r = 0
    for j, (ix, L) in enumerate(zip(ixs, pinvs)):
        member[r : r + len(ix), j] = 1.0
        r += len(ix)
        rows = np.asarray(ix, dtype=int)
        blocks.append(L @ S_all[np.ix_(rows, flat)] if L is not None else np.zeros((len(ix), flat.size)))
    P = np.concatenate(blocks, axis=0) if blocks else np.zeros((0, 0))
    return member.T @ (P * P.T) @ member


def _canonical_corr(
    S_all: np.ndarray, ia: Sequence[int], ib: Sequence[int], La: np.ndarray | None = None, Lb: np.ndarray | None = None
) -> float:
    """Largest canonical correlation of candidates ``ia`` and ``ib`` given the state:
    ``ρ² = λ_max(S_aa⁺ S_ab S_bb⁺ S_ba)``. ``La``, ``Lb``: the pseudo-inverses
    :func:`_pinv` of ``S_aa``, ``S_bb`` if already computed."""
    Sab = S_all[np.ix_(ia, ib)]
    if La is None:
        La = _pinv(S_all[np.ix_(ia, ia)])
    if Lb is None:
        Lb = _pinv(S_all[np.ix_(ib, ib)])
    if La is None or Lb is None:
        return 0.0
    M = La @ Sab @ Lb @ Sab.T
    ev = np.linalg.eigvals(M).real
    return float(np.sqrt(np.clip(np.max(ev) if ev.size else 0.0, 0.0, 1.0)))


#: The one ranking and significance rule, said wherever candidates are shown.
RULE = (
    "Candidates are ranked by p, the chance of a Δχ² this large on its dof if the effect were absent "
    "(equal p: the larger Δχ² first); p adj = min(1, m·p) over the m candidates tried (Bonferroni), and a "
    "candidate is significant when p adj < α, the family-wise level."
)


def _p_text(p: float, name: str = "p") -> str:
    """``p = 0.0031``; below double precision's resolution of 1 − P, ``p < 1e-16``."""
    return f"{name} < 1e-16" if p < 1e-16 else f"{name} = {p:.2g}"


def explain(c: Candidate, alpha: float) -> str:
    """One paragraph: the signature seen, its strength, and the physical cause."""
    seen = (
        ", ".join(f"{s} ({100 * v:.0f}%)" for s, v in sorted(c.sensors.items(), key=lambda kv: -kv[1]) if v > 0.05)
        or "no sensor"
    )
    head = (
        f"{c.id}: adding it would remove Δχ² = {c.delta_chi2:.1f} on {c.dof} degree"
        f"{'s' if c.dof != 1 else ''} of freedom ({_p_text(c.p_value)}; corrected for the "
        f"candidates tried, {_p_text(c.p_adjusted, 'p adj')}, "
        f"{'significant' if c.significant else 'not significant'} at family-wise "
        f"α = {alpha:g}); the signature is seen in {seen}."
    )
    if not c.identifiable:
        if c.absorbed >= ABSORB_TOL:
            head += (
                " It cannot be told apart from elements already estimated"
                + (f" ({', '.join(c.aliases_state)})" if c.aliases_state else "")
                + ": the data carry no separate information on it."
            )
        elif c.aliases_candidates:
            head += (
                " It is indistinguishable from " + ", ".join(a for a, _ in c.aliases_candidates) + " with these data."
            )
    elif c.absorbed > 0.5 and c.aliases_state:
        head += (
            f" {100 * c.absorbed:.0f}% of its signature could be absorbed by "
            f"{', '.join(c.aliases_state)}, but enough remains to identify it."
        )
    return head + " " + c.effect.explanation
