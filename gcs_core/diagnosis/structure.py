"""Residual-structure search: what does a misfit sensor's residual follow?

For each residual component of a sensor and each channel GCS can form at its frames
(:mod:`gcs_core.diagnosis.channels`), a binned-means test: the channel's range is cut into
``K`` bins (quantiles, or the channel's own levels when it has few) and the residual's
mean per bin is compared with its scatter within the bins, a one-way analysis of variance
(Fisher's F test; Scheffé, *The Analysis of Variance*, Wiley 1959, ch. 3). Any form of
dependence shows, linear or not, a step or a bump.

Correlated residuals. Post-fit residuals are not white (the attitude's wander, a slow
drift); a slow channel (a temperature, the orbit phase, time) puts neighbouring samples in
one bin, and white-noise F would then see structure everywhere. The residuals are first
averaged in consecutive blocks (at most :data:`MAX_BLOCKS`); the lag-1 autocorrelation
``ρ`` of the within-bin deviations of the block means (the part the channel does not
explain) then gives the variance inflation of a bin mean under an AR(1) model,
``f = (1 + ρ)/(1 − ρ)`` (Bretherton et al., J. Climate 12, 1999, Eq. 31: the effective
sample size ``n (1 − ρ)/(1 + ρ)``). The statistic is ``F/f`` on ``(K − 1, n/f − K)``
degrees of freedom: conservative for a fast channel, honest for a slow one.

Family-wise control: every test of the search (sensors × components × channels) is one of
``m``; ``p adj = min(1, m p)`` (Bonferroni), significant when below the session's α.

Channel aliases: two channels are aliases at a sensor's frames when one explains
:data:`ALIAS_R2` of the other's variance (binned on each other, both ways); a channel is an
alias of the orbit phase when its first two harmonics explain that much of it. A finding
names its aliases, and the channel the effect is offered on is the most physical of the
group (:func:`physical_order`): a temperature, then the orbit phase itself, then the rest.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from gcs_core.diagnosis.channels import Channel, harmonics

#: at most this many bins per test
N_BINS = 10
#: residuals are averaged into at most this many consecutive blocks before the test
MAX_BLOCKS = 1200
#: share of one channel's variance another must explain to be called its alias
ALIAS_R2 = 0.9
#: share from which two channels are reported as following one another (not yet aliases)
RELATED_R2 = 0.5
#: at most this many dependencies are reported per sensor
TOP_PER_SENSOR = 4


@dataclass(frozen=True)
class Dependency:
    """A residual component found to follow a channel.

    Attributes
    ----------
    sensor, component : the residual; unit : the sensor's measurement unit.
    channel : the channel's name (``aux:tam_temp``, ``orbit_phase``, ...); label : as shown.
    kind : the channel's kind; channel_unit : its unit.
    centers : (K,) channel value at each bin (median); means : (K,) residual mean per bin
        [sensor unit]; counts : (K,) samples per bin.
    F : the statistic ``F/f``; dof : ``(K − 1, n_eff − K)``; inflation : ``f``.
    p_value, p_adjusted : the test's p and its Bonferroni correction over the search.
    share : fraction of the component's residual variance the bin means explain.
    catalogue : catalogue effects with this form (ids), those not in the state.
    aliases : other channels that are aliases of this one at this sensor's frames.
    """

    sensor: str
    component: str
    unit: str
    channel: str
    label: str
    kind: str
    channel_unit: str
    centers: np.ndarray
    means: np.ndarray
    counts: np.ndarray
    F: float
    dof: tuple[float, float]
    inflation: float
    p_value: float
    p_adjusted: float = 1.0
    share: float = 0.0
    catalogue: tuple[str, ...] = ()
    aliases: tuple[str, ...] = ()

    @property
    def size(self) -> float:
        """Peak-to-peak of the bin means [sensor unit]."""
        return float(np.max(self.means) - np.min(self.means))

    def significant(self, alpha: float) -> bool:
        return self.p_adjusted < alpha

    def as_report(self) -> dict:
        lo, hi = int(np.argmin(self.means)), int(np.argmax(self.means))
        return {
            "sensor": self.sensor,
            "component": self.component,
            "unit": self.unit,
            "channel": self.channel,
            "channel_unit": self.channel_unit,
            "kind": self.kind,
            "low": {"residual": float(self.means[lo]), "at": float(self.centers[lo])},
            "high": {"residual": float(self.means[hi]), "at": float(self.centers[hi])},
            "peak_to_peak": self.size,
            "F": round(self.F, 3),
            "dof": [round(self.dof[0], 1), round(self.dof[1], 1) if math.isfinite(self.dof[1]) else None],
            "correlation_inflation": round(self.inflation, 3),
            "p_value": self.p_value,
            "p_adjusted": self.p_adjusted,
            "variance_share": round(self.share, 4) if math.isfinite(self.share) else None,  # None: a score test
            "catalogue_forms": list(self.catalogue),
            "aliases": list(self.aliases),
            "bins": {"at": [float(x) for x in self.centers], "mean": [float(x) for x in self.means]},
        }


@dataclass(frozen=True)
class StructureReport:
    """What the search found.

    Attributes
    ----------
    searched : sensors searched, with why ("exceeds the noise" or "on request").
    tests : number of tests ``m`` (the Bonferroni factor); alpha : the family-wise level.
    found : significant dependencies, most significant first.
    best : sensor -> its strongest tests (significant or not), for display.
    alias_groups : sensor -> groups of channels that are aliases of each other there.
    relations : sensor -> ``(a, b, R²)`` of the channel pairs that follow one another
        (R² ≥ :data:`RELATED_R2`; for the orbit phase, its harmonics' share).
    """

    searched: Mapping[str, str]
    tests: int
    alpha: float
    found: tuple[Dependency, ...] = ()
    best: Mapping[str, tuple[Dependency, ...]] = field(default_factory=dict)
    alias_groups: Mapping[str, tuple[tuple[str, ...], ...]] = field(default_factory=dict)
    relations: Mapping[str, tuple[tuple[str, str, float], ...]] = field(default_factory=dict)

    def for_sensor(self, sensor: str) -> list[Dependency]:
        return [d for d in self.found if d.sensor == sensor]

    def as_report(self) -> dict:
        return {
            "searched": dict(self.searched),
            "tests": self.tests,
            "alpha": self.alpha,
            "found": [d.as_report() for d in self.found],
            "alias_groups": {k: [list(g) for g in v] for k, v in self.alias_groups.items()},
            "channel_relations": {
                k: [{"a": a, "b": b, "r2": round(r2, 3)} for a, b, r2 in v] for k, v in self.relations.items()
            },
        }


def _bins(x: np.ndarray, periodic: bool) -> np.ndarray:
    """Bin index (0..K−1) of each value: the channel's levels when it has at most
    :data:`N_BINS`, else quantile bins (equal-width on the circle for a phase). Levels and
    quantiles come from at most ~5000 of the values (a long span's channel is smooth)."""
    sub = x[:: max(1, x.size // 5000)]
    levels = np.unique(sub)
    if levels.size <= N_BINS:
        return np.minimum(np.searchsorted(levels, x), max(levels.size - 1, 0))
    if periodic:
        return np.minimum((np.mod(x, 2 * np.pi) / (2 * np.pi) * N_BINS).astype(int), N_BINS - 1)
    edges = np.unique(np.quantile(sub, np.linspace(0, 1, N_BINS + 1)[1:-1]))
    return np.searchsorted(edges, x, side="right")


def binned_test(z: np.ndarray, x: np.ndarray, *, periodic: bool = False, bins: np.ndarray | None = None):
    """The binned-means F test of ``z`` (time-ordered, normalized residual) against ``x``
    (``bins``: the bin of each value when already known, :func:`_bins`).

    Returns ``(F/f, dof1, dof2, f, p, centers, means, counts, share)`` with ``means`` in the
    units of ``z``, or None when there are fewer than two usable bins.
    """
    n = z.size
    b = max(1, math.ceil(n / MAX_BLOCKS))
    nb = n // b
    if nb < 8:
        return None
    bins_f = _bins(x, periodic) if bins is None else bins
    zb = z[: nb * b].reshape(nb, b).mean(axis=1)
    kb = bins_f[: nb * b].reshape(nb, b)[:, b // 2]
    labels, kb = np.unique(kb, return_inverse=True)
    K = labels.size
    counts = np.bincount(kb, minlength=K).astype(float)
    if K < 2 or np.count_nonzero(counts >= 2) < 2 or nb - K < 4:
        return None
    means = np.bincount(kb, weights=zb, minlength=K) / np.maximum(counts, 1)
    grand = zb.mean()
    e = zb - means[kb]
    ssb = float(np.sum(counts * (means - grand) ** 2))
    ssw = float(np.sum(e**2))
    tot = ssb + ssw
    rho = float(np.sum(e[1:] * e[:-1]) / ssw) if ssw > 0 else 0.0
    rho = min(max(rho, 0.0), 0.98)
    f = (1.0 + rho) / (1.0 - rho)
    d1, d2 = K - 1.0, max(nb / f - K, 1.0)
    F = (ssb / d1) / (ssw / (nb - K)) / f if ssw > 0 else math.inf
    p = float(stats.f.sf(F, d1, d2))
    xs = x[: nb * b].reshape(nb, b)[:, b // 2]
    centers = np.array([np.median(xs[kb == k]) for k in range(K)])
    if periodic:
        centers = np.array([_circ_mean(xs[kb == k]) for k in range(K)])
    # a mean per bin over the samples (not the blocks) for the sizes shown
    return F, d1, d2, f, p, centers, means, counts * b, ssb / tot if tot > 0 else 0.0


def _circ_mean(a: np.ndarray) -> float:
    return float(np.mod(np.arctan2(np.mean(np.sin(a)), np.mean(np.cos(a))), 2 * np.pi))


def _explained(y: np.ndarray, X: np.ndarray) -> float:
    """Share of ``y``'s variance a least-squares fit on the columns of ``X`` explains."""
    yc = y - y.mean()
    A = np.column_stack([np.ones(y.size), X])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    res = y - A @ coef
    vy = float(yc @ yc)
    return 1.0 - float(res @ res) / vy if vy > 0 else 0.0


def channel_r2(channels: Sequence[Channel], *, floor: float = RELATED_R2) -> dict[tuple[str, str], float]:
    """(a, b) -> how much one channel explains of the other at these frames, for the pairs at
    or above ``floor``: the squared correlation, or for the orbit phase the share of the
    other's variance its first two harmonics explain (module docstring). FOV pairs aside."""
    step = max(1, len(channels[0].values) // 2000) if channels else 1
    vals = {c.name: np.asarray(c.values, float)[::step] for c in channels}
    out: dict[tuple[str, str], float] = {}
    for i, a in enumerate(channels):
        for b in channels[i + 1 :]:
            if a.kind == "fov" and b.kind == "fov":
                continue
            ya, yb = vals[a.name], vals[b.name]
            ok = np.isfinite(ya) & np.isfinite(yb)
            if np.count_nonzero(ok) < 20:
                continue
            if a.periodic or b.periodic:
                u, other = (ya, yb) if a.periodic else (yb, ya)
                X = np.column_stack([*harmonics(u[ok], 1), *harmonics(u[ok], 2)])
                r2 = _explained(other[ok], X)
            else:
                c = np.corrcoef(ya[ok], yb[ok])[0, 1]
                r2 = float(c * c) if np.isfinite(c) else 0.0
            if r2 >= floor:
                out[(a.name, b.name)] = float(r2)
    return out


def channel_aliases(channels: Sequence[Channel], *, r2: float = ALIAS_R2) -> dict[str, tuple[str, ...]]:
    """channel -> the other channels that are its aliases at these frames (module docstring)."""
    out: dict[str, list[str]] = {c.name: [] for c in channels}
    for a, b in channel_r2(channels, floor=r2):
        out[a].append(b)
        out[b].append(a)
    return {k: tuple(v) for k, v in out.items()}


def alias_groups(aliases: Mapping[str, Iterable[str]]) -> tuple[tuple[str, ...], ...]:
    """Connected groups (two or more channels) of the alias relation, most physical first."""
    seen: set[str] = set()
    groups = []
    for start in aliases:
        if start in seen or not aliases[start]:
            continue
        stack, g = [start], []
        while stack:
            c = stack.pop()
            if c in seen:
                continue
            seen.add(c)
            g.append(c)
            stack.extend(aliases.get(c, ()))
        groups.append(tuple(sorted(g, key=physical_order)))
    return tuple(groups)


def physical_order(name: str) -> tuple[int, str]:
    """Sort key: which channel of an alias group an effect is best offered on — a
    temperature (thermo-elastic, thermal drift), then the orbit phase itself, a heater or
    current, other aux channels, the Sun angle and eclipse, the rest."""
    low = name.lower()
    if name.startswith("aux:") and "temp" in low:
        rank = 0
    elif name == "orbit_phase":
        rank = 1
    elif (name.startswith("aux:") and any(k in low for k in ("heater", "mtb", "current"))) or name.startswith("int:"):
        rank = 2
    elif name.startswith("aux:"):
        rank = 3
    elif name in ("sun_angle", "eclipse"):
        rank = 4
    else:
        rank = 5
    return rank, name


#: catalogue effects whose residual follows a channel of this kind (``{ch}``: the aux name)
FORMS: dict[str, tuple[str, ...]] = {
    "aux": ("contamination_{ch}",),
    "orbit": ("model.stellar_aberration", "model.solar_aberration", "model.sun_parallax", "model.field_model"),
    "sun": ("model.solar_aberration", "model.sun_parallax"),
    "eclipse": (),
    "rate": ("time_offset", "scale_misalignment"),
    "angle": ("scale_misalignment",),
    "fov": ("alignment", "scale", "bias", "nonorthogonality", "harmonic", "transfer_function"),
    "telemetry": (),
    "time": ("bias_instability",),
    "aux_integral": (),  # the gyro's bias following the switch: a family (gyro_steps.py)
}


def catalogue_forms(sensor: str, ch: Channel, catalogue_ids: Iterable[str]) -> tuple[str, ...]:
    """The catalogue effects (ids in ``catalogue_ids``) with the form of a dependency on ``ch``."""
    ids = dict.fromkeys(catalogue_ids)  # in the catalogue's order: a set's would vary with the hash seed
    out = []
    for form in FORMS.get(ch.kind, ()):
        name = form.format(ch=ch.label)
        for eid in (name, f"{sensor}.{name}"):
            if eid in ids:
                out.append(eid)
        if ch.kind in ("rate", "angle", "time"):  # a gyro's effect shows in every sensor
            out += [i for i in ids if i.endswith("." + name) and i not in out and not i.startswith(sensor + ".")]
    return tuple(out)


def search(
    residuals: Mapping,
    channels: Mapping[str, Sequence[Channel]],
    *,
    alpha: float,
    why: Mapping[str, str],
    catalogue_ids: Iterable[str] = (),
    extra: Sequence[Dependency] = (),
) -> StructureReport:
    """Test every residual component of the sensors in ``why`` against each of its channels.

    ``residuals``: sensor -> :class:`~gcs_core.estimators.results.SensorResiduals` (used frames,
    residual and σ); ``channels``: sensor -> its :class:`Channel` list at its frames.
    ``extra``: tests made elsewhere (the gyro's, :mod:`gcs_core.diagnosis.gyro_search`),
    with their unadjusted p, counted in the family-wise correction with the others.
    """
    ids = tuple(catalogue_ids)
    rows: list[Dependency] = []
    groups: dict[str, tuple[tuple[str, ...], ...]] = {}
    relations: dict[str, tuple[tuple[str, str, float], ...]] = {}
    m = 0
    for sensor in why:
        res = residuals.get(sensor)
        chans = channels.get(sensor, ())
        if res is None or not chans:
            continue
        r2 = channel_r2(chans)
        relations[sensor] = tuple(sorted(((a, b, v) for (a, b), v in r2.items()), key=lambda x: -x[2]))
        aliases: dict[str, list[str]] = {c.name: [] for c in chans}
        for (a, b), v in r2.items():
            if v >= ALIAS_R2:
                aliases[a].append(b)
                aliases[b].append(a)
        groups[sensor] = alias_groups(aliases)
        r = np.asarray(res.residual, dtype=float)
        binned = {}  # channel -> (finite, bin of each frame): the same for every component
        for ch in chans:
            vals = np.asarray(ch.values, float)
            fin = np.isfinite(vals)
            k = np.zeros(vals.size, dtype=int)
            k[fin] = _bins(vals[fin], ch.periodic)
            binned[ch.name] = (fin, k)
        for ci, comp in enumerate(res.components):
            ok = np.asarray(res.used, bool) & np.isfinite(r[:, ci])
            z = r[ok, ci] / float(res.sigma[ci])
            for ch in chans:
                fin_all, k_all = binned[ch.name]
                fin = fin_all[ok]
                m += 1
                out = binned_test(
                    z[fin], np.asarray(ch.values, float)[ok][fin], periodic=ch.periodic, bins=k_all[ok][fin]
                )
                if out is None:
                    continue
                F, d1, d2, f, p, centers, means, counts, share = out
                rows.append(
                    Dependency(
                        sensor,
                        comp,
                        res.unit,
                        ch.name,
                        ch.label,
                        ch.kind,
                        ch.unit,
                        centers,
                        means * float(res.sigma[ci]),
                        counts,
                        float(F),
                        (d1, d2),
                        f,
                        p,
                        share=share,
                        catalogue=catalogue_forms(sensor, ch, ids),
                        aliases=tuple(aliases.get(ch.name, ())),
                    )
                )
    rows += list(extra)
    m = max(m + len(extra), 1)
    rows = [_adjust(d, m) for d in rows]
    rows.sort(key=lambda d: (d.p_value, -d.F))
    found = tuple(d for d in rows if d.p_adjusted < alpha)
    best: dict[str, list[Dependency]] = {}
    for d in rows:
        lst = best.setdefault(d.sensor, [])
        if len(lst) < TOP_PER_SENSOR:
            lst.append(d)
    return StructureReport(dict(why), m, alpha, found, {k: tuple(v) for k, v in best.items()}, groups, relations)


def _adjust(d: Dependency, m: int) -> Dependency:
    from dataclasses import replace

    return replace(d, p_adjusted=min(1.0, d.p_value * m))


def strongest(found: Sequence[Dependency], sensor: str) -> list[Dependency]:
    """A sensor's significant dependencies, one per channel (its strongest component),
    most significant first."""
    seen: dict[str, Dependency] = {}
    for d in found:
        if d.sensor != sensor:
            continue
        if d.channel not in seen or (d.p_value, -d.F) < (seen[d.channel].p_value, -seen[d.channel].F):
            seen[d.channel] = d
    return sorted(seen.values(), key=lambda d: (d.p_value, -d.F))
