"""Streaming linearization of a calibration problem (seed Eq 3-1, 3-2: the ``H`` and ``r``).

:func:`iter_blocks` walks the data chunk by chunk (:data:`~gcs_core.problem.build.CHUNK_FRAMES`
frames) and yields, per sensor chunk, residuals ``r = y − h(x)`` and Jacobian columns
``H = ∂h/∂x`` for any list of elements, the attitude partials chained through the
attitude provider; :func:`linearize` gathers whole-span :class:`Linearization` objects.
The batch estimator, the Kalman filter, the predictor and the diagnosis all read the data
through here, so memory is bounded by the chunk, not the span. It builds on
:mod:`gcs_core.problem.build` (the state definition).
"""

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from gcs_core.cancel import checkpoint
from gcs_core.models.base import Geometry, Prediction
from gcs_core.problem.build import Problem
from gcs_core.problem.curvature import block_curvature
from gcs_core.problem.kernels import GRAM_TILE_ROWS
from gcs_core.problem.prepare import HeldChannels, SensorData


@dataclass(frozen=True)
class Linearization:
    """One sensor's residuals and Jacobian at a state.

    Attributes
    ----------
    name : sensor name.
    y_pred : (N, m) predicted measurements.
    r : (N, m) residual ``y − h(x)`` (wrapped where the model says so).
    H : (N, m, k) partials with respect to ``columns``.
    valid : (N,) frames where the model is defined.
    sigma : (m,) measurement noise.
    """

    name: str
    y_pred: np.ndarray
    r: np.ndarray
    H: np.ndarray
    valid: np.ndarray
    sigma: np.ndarray


@dataclass(frozen=True)
class Block:
    """One sensor's residuals and partials over one chunk of its frames (:func:`iter_blocks`).

    Attributes
    ----------
    sensor : the sensor; lo, hi : its frames ``lo..hi−1``.
    geom : the chunk's geometry with the attitude.
    y_pred, r : (n, m) prediction and residual (NaN where the model is undefined).
    valid : (n,) frames where the model is defined (finite residual).
    used : (n,) valid and not excluded.
    cols : (k_s,) positions in the requested columns of the columns this sensor's
        measurements depend on (the attitude's elements and its own parameters).
    H : (n, m, k_s) partials over ``cols``; weighted (``R^-1/2 H``, zero rows where not
        used) when the blocks were asked weighted, raw (NaN where invalid) otherwise.
    Hr : (n·m, k_s + 1) ``[R^-1/2 H | R^-1/2 r]`` (unused rows zero) when the blocks were
        asked ``augmented`` (``H`` is then a view of its first k_s columns), else None.
    curv : ``((i, j, K_ij), ...)`` over block columns, the Newton terms of the model's
        parameter pairs when asked ``second_order``
        (:func:`~gcs_core.problem.curvature.block_curvature`).
    pred : the model's :class:`~gcs_core.models.base.Prediction` of the chunk.
    G : (k_s + 1, k_s + 1) ``Hrᵀ Hr`` when the blocks were asked ``gram`` and it was formed
        without storing the rows (then ``H`` and ``Hr`` are None).
    """

    sensor: SensorData
    lo: int
    hi: int
    geom: Geometry
    y_pred: np.ndarray
    r: np.ndarray
    valid: np.ndarray
    used: np.ndarray
    cols: np.ndarray
    H: np.ndarray | None
    Hr: np.ndarray | None = None
    curv: tuple = ()
    pred: Prediction | None = None
    G: np.ndarray | None = None

    @property
    def name(self) -> str:
        return self.sensor.name

    def gram(self) -> np.ndarray:
        """``[H r]ᵀ [H r]`` (k_s + 1, k_s + 1): ``G`` when the block was formed without its rows."""
        if self.G is not None:
            return self.G
        if self.Hr is None:
            raise ValueError("this block carries neither its rows nor their Gram matrix")
        return self.Hr.T @ self.Hr

    def weighted_residual(self) -> np.ndarray:
        """(n·m,) ``R^-1/2 r`` with unused frames zero."""
        return (np.where(self.used[:, None], self.r, 0.0) / self.sensor.sigma).reshape(-1)


def sensor_geometry(problem: Problem, sd: SensorData, values: Mapping[str, float], geom=None):
    att = problem.attitude.evaluate(values, sd.t)
    g = geom if geom is not None else sd.geom
    if att.C_BI is not None:
        g = replace(g, C_BI=att.C_BI, omega_B=att.omega_B)
    else:
        g = replace(g, spin_axis_I=att.spin_axis_I)
    return g, att


def window_geometry(g, lo: int, hi: int, n: int):
    """Frames ``lo..hi−1`` of an N-frame geometry (views; the aux channels stay lazy)."""

    def cut(a):
        return a[lo:hi] if isinstance(a, np.ndarray) and a.ndim >= 1 and a.shape[0] == n else a

    aux = g.aux.window(lo, hi) if isinstance(g.aux, HeldChannels) else {k: cut(v) for k, v in g.aux.items()}
    return replace(
        g,
        t=g.t[lo:hi],
        C_BI=cut(g.C_BI),
        spin_axis_I=cut(g.spin_axis_I),
        r_I=cut(g.r_I),
        v_I=cut(g.v_I),
        sun_I=cut(g.sun_I),
        B_I=cut(g.B_I),
        star_I=cut(g.star_I),
        omega_B=cut(g.omega_B),
        aux=aux,
        extra={k: cut(v) for k, v in g.extra.items()},
    )


def chunk_windows(
    problem: Problem, sensors: Sequence[SensorData], chunk: int | None = None
) -> list[list[tuple[int, int]]]:
    """Time windows of at most ``chunk`` frames of any sensor: per window, each sensor's
    frame range ``(lo, hi)``. Windows end on the gyro-carried attitude's block edges, so
    that a window needs one block of its propagation."""
    chunk = max(1, int(chunk or problem.chunk_frames))
    edges = problem.attitude.block_edges()
    pos = [0] * len(sensors)
    cur, e = -np.inf, 0
    out = []
    while any(p < sd.n for p, sd in zip(pos, sensors)):
        cand = [sd.t[p + chunk - 1] for p, sd in zip(pos, sensors) if p + chunk - 1 < sd.n]
        while e < edges.size and edges[e] <= cur:
            e += 1
        if e < edges.size:
            cand.append(edges[e])
        edge = min(cand) if cand else np.inf
        hi = [int(np.searchsorted(sd.t, edge, side="right")) if np.isfinite(edge) else sd.n for sd in sensors]
        if any(h > p for h, p in zip(hi, pos)):
            out.append(list(zip(pos, hi)))
        pos, cur = hi, edge
    return out


def _sensor_columns(problem: Problem, sd: SensorData, att_names, col_index):
    """This sensor's columns: attitude elements first (positions in ``att_names``), then
    its own parameters; returns (att positions, param (local name, block column), cols)."""
    att_sel = [a for a, nm in enumerate(att_names) if nm in col_index]
    cols = [col_index[att_names[a]] for a in att_sel]
    where = {c: i for i, c in enumerate(cols)}
    par = []
    for local, el in problem.param_map[sd.name].items():
        j = col_index.get(el)
        if j is None:
            continue
        if j not in where:
            where[j] = len(cols)
            cols.append(j)
        par.append((local, where[j]))
    return np.array(att_sel, int), par, np.array(cols, int)


def iter_blocks(
    problem: Problem,
    values: Mapping[str, float],
    columns: Sequence[str] = (),
    *,
    exclude: Mapping[str, np.ndarray] | None = None,
    weighted: bool = False,
    sensors: Sequence[str] | None = None,
    geoms: Mapping[str, object] | None = None,
    chunk: int | None = None,
    jacobian: bool = True,
    work: dict | None = None,
    augmented: bool = False,
    second_order: bool = False,
    gram: bool = False,
) -> Iterator[Block]:
    """Residuals and partials of every (or the named) sensor at ``values``, chunk by chunk.

    Windows of time (:func:`chunk_windows`) are visited in order; in each, the attitude is
    evaluated and every sensor's frames are predicted and linearized. A block holds only
    the columns its sensor depends on (``Block.cols``), so memory is O(chunk · k_s) and
    the work is that of the non-zero part of H.

    ``exclude`` flags frames (True = not used). ``work`` (a dict kept by the caller across
    calls) lends chunk-sized buffers for H: fresh pages cost more than the arithmetic on
    them; a block's H is then valid until the next block of the same sensor is produced.

    What a block carries is set by the flags, one form each (a flag the form cannot use
    is refused, :func:`_check_form`):

    ======================================  ==========================================
    asked                                   the block carries
    ======================================  ==========================================
    ``jacobian=False``                      ``r``, ``y_pred``, masks; no H (the other
                                            flags then do nothing)
    (default)                               ``H`` raw, NaN where invalid
    ``weighted``                            ``H = R^-1/2 H``, unused rows zero
    ``weighted, augmented``                 ``Hr = [R^-1/2 H | R^-1/2 r]`` (n·m, k_s+1),
                                            ``H`` a view of its first k_s columns: one
                                            ``Hrᵀ Hr`` gives ``Hᵀ R⁻¹ H``, ``Hᵀ R⁻¹ r``
                                            and ``rᵀ R⁻¹ r``
    ``weighted, augmented, gram``           ``G = Hrᵀ Hr`` and no H where the attitude
                                            forms it without storing the rows
                                            (:meth:`FrameAttitude.fill_gram`); ``Hr``
                                            as above elsewhere
    ``second_order`` (with the Jacobian)    also ``curv``, the model's second partials
                                            contracted with the weighted residuals
                                            (:mod:`gcs_core.problem.curvature`)
    ======================================  ==========================================
    """
    _check_form(weighted=weighted, augmented=augmented, gram=gram)
    col_index = {c: j for j, c in enumerate(columns)}
    sds = [sd for sd in problem.sensors if sensors is None or sd.name in sensors]
    att_names = tuple(problem.attitude.names)
    layout = {sd.name: _sensor_columns(problem, sd, att_names, col_index) for sd in sds}
    for window in chunk_windows(problem, sds, chunk):
        checkpoint()  # esc in the TUI stops a fit or a ranking here (gcs_core.cancel)
        for sd, (lo, hi) in zip(sds, window):
            if hi <= lo:
                continue
            base = geoms.get(sd.name) if geoms is not None and sd.name in geoms else sd.geom
            geom = window_geometry(base, lo, hi, sd.n)
            att_sel, par, cols = layout[sd.name]
            fr = problem.attitude.frames(values, sd.t[lo:hi], partials=jacobian and att_sel.size > 0)
            if fr.C_BI is not None:
                geom = replace(geom, C_BI=fr.C_BI, omega_B=fr.omega_B)
            else:
                geom = replace(geom, spin_axis_I=fr.spin_axis_I)
            pred = sd.model.predict(geom, problem.params_of(sd.name, values))
            r = sd.model.residual(sd.y[lo:hi], pred.y, geom=geom)
            valid = np.array(pred.valid, bool)
            for c in range(r.shape[1]):  # column by column: a reduction over axis 1 is slow
                valid &= np.isfinite(r[:, c])
            used = (
                valid
                if exclude is None or sd.name not in exclude
                else valid & ~np.asarray(exclude[sd.name][lo:hi], bool)
            )
            curv = block_curvature(pred.d2_par, par, r, used, sd.sigma) if second_order and jacobian else ()
            H = Hr = G = None
            if jacobian and cols.size:
                H, Hr, G = _block_partials(
                    sd,
                    pred,
                    fr,
                    r,
                    used,
                    att_sel,
                    par,
                    cols.size,
                    work,
                    weighted=weighted,
                    augmented=augmented,
                    gram=gram,
                )
            del fr  # the attitude's block buffers may be reused
            yield Block(sd, lo, hi, geom, pred.y, r, valid, used, cols, H, Hr, curv, pred, G)


def _check_form(*, weighted: bool, augmented: bool, gram: bool) -> None:
    """Refuse flags of :func:`iter_blocks` that its form cannot use."""
    if augmented and not weighted:
        raise ValueError("iter_blocks: augmented rows [R^-1/2 H | R^-1/2 r] need weighted=True")
    if gram and not augmented:
        raise ValueError("iter_blocks: gram (Hrᵀ Hr) needs augmented=True")


def _block_partials(
    sd, pred, fr, r, used, att_sel, par, k: int, work, *, weighted: bool, augmented: bool, gram: bool
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """(H, Hr, G) of one block in the form :func:`iter_blocks` was asked for (its table)."""
    w = (used[:, None] * (1.0 / sd.sigma)[None, :]) if weighted else None  # R^-1/2
    aug = int(augmented)
    m = len(sd.sigma)
    n = len(used)
    buf = _buffer(work, sd.name, (n, m, k + aug))
    P = _buffer(work, (sd.name, "P"), (len(par) + aug, n, m)) if getattr(fr, "can_fill_rows", False) else None
    G = np.zeros((k + 1, k + 1)) if gram and P is not None else None
    tile = _buffer(work, (sd.name, "tile"), (max(GRAM_TILE_ROWS, m), k + 1)) if G is not None else None
    if (
        _block_jacobian(pred, fr, att_sel, par, k, w, buf, r if aug else None, P, gram=None if G is None else (G, tile))
        is None
    ):
        assert G is not None  # None comes back only when the rows went into G
        return None, None, np.tril(G) + np.tril(G, -1).T  # chain_gram fills the lower triangle
    if weighted and not np.all(used):
        buf[~used] = 0.0  # NaN partials/residuals of unused frames
    return (buf[:, :, :k] if aug else buf), (buf.reshape(-1, k + 1) if aug else None), None


def _buffer(work: dict | None, key, shape) -> np.ndarray:
    """An uninitialized array of ``shape``, from the caller's workspace when given."""
    if work is None:
        return np.empty(shape)
    size = int(np.prod(shape))
    buf = work.get(key)
    if buf is None or buf.size < size:
        buf = work[key] = np.empty(size)
    return buf[:size].reshape(shape)


def _block_jacobian(
    pred, fr, att_sel, par, k: int, w, H: np.ndarray, r=None, P: np.ndarray | None = None, gram=None
) -> np.ndarray | None:
    """(n, m, k) partials of one block, into the first k columns of ``H`` (n, m, ≥ k):
    ``∂y/∂δθ · ∂δθ/∂x`` in the attitude columns, the model's own partials in the
    parameter columns; rows scaled by ``w`` (n, m) if given. With ``r`` (weighted
    blocks), ``w r`` goes into column k.

    Where the attitude can fill whole rows in one pass (:meth:`FrameAttitude.fill_rows`),
    the parameter columns are first formed contiguously in ``P`` (len(par) (+1), n, m)
    and copied in that pass: a strided column-by-column write costs several times more.
    With ``gram = (G, tile)`` the rows are summed into ``G`` instead where the attitude
    can (:meth:`FrameAttitude.fill_gram`), and None is returned.
    """
    D = pred.d_att
    ka = att_sel.size
    if P is not None and ka:
        for q, (local, _) in enumerate(par):
            if w is None:
                P[q] = pred.d_par[local]
            else:
                np.multiply(pred.d_par[local], w, out=P[q])
        pcol = [j for _, j in par]
        if r is not None:
            np.multiply(r, w, out=P[len(par)])  # R^-1/2 r
            pcol.append(k)
        if gram is not None and fr.fill_gram(D, att_sel, gram[0], gram[1], w=w, P=P, pcol=pcol):
            return None
        if fr.fill_rows(D, att_sel, H, w=w, P=P, pcol=pcol):
            return H
    if ka:
        fr.chain(D, att_sel, out=H[:, :, :ka], w=w)
    for local, j in par:
        d = pred.d_par[local]
        if j < ka:
            H[:, :, j] += d if w is None else d * w
        elif w is None:
            H[:, :, j] = d
        else:
            np.multiply(d, w, out=H[:, :, j])
    if r is not None:
        np.multiply(r, w, out=H[:, :, k])  # R^-1/2 r
    return H


def linearize(
    problem: Problem,
    values: Mapping[str, float],
    columns: Sequence[str],
    *,
    sensors: Sequence[str] | None = None,
    geoms: Mapping[str, object] | None = None,
) -> list[Linearization]:
    """Residuals and partials of every (or the named) sensor at ``values``, whole span.

    The (N, m, k) arrays of this form grow with the span; the estimators stream
    :func:`iter_blocks` instead.
    """
    k = len(columns)
    sds = [sd for sd in problem.sensors if sensors is None or sd.name in sensors]
    out = {}
    for sd in sds:
        m = len(sd.sigma)
        out[sd.name] = (
            np.full((sd.n, m), np.nan),
            np.full((sd.n, m), np.nan),
            np.zeros(sd.n, bool),
            np.zeros((sd.n, m, k)),
        )
    for blk in iter_blocks(problem, values, columns, sensors=sensors, geoms=geoms):
        y_pred, r, valid, H = out[blk.name]
        y_pred[blk.lo : blk.hi] = blk.y_pred
        r[blk.lo : blk.hi] = blk.r
        valid[blk.lo : blk.hi] = blk.valid
        if blk.H is not None:
            H[blk.lo : blk.hi, :, blk.cols] = blk.H
    return [Linearization(sd.name, *out[sd.name][:2], out[sd.name][3], out[sd.name][2], sd.sigma) for sd in sds]
