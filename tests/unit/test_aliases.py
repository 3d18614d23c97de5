"""Naming the combinations a fit leaves to the a priori (gcs_core.diagnosis.aliases).

Known information matrices: two scanners each seeing only ``ΔΦ − c ε_H`` (two exact
aliases, which an eigen-decomposition blends since both eigenvalues are zero), a pair seen
with a twentieth of the a priori's information, and one element weak on its own.
"""

from __future__ import annotations

import numpy as np

from gcs_core.diagnosis.aliases import set_by_prior, weak_directions

NAMES = ["S1.d_phi", "S1.eps_H", "S2.d_phi", "S2.eps_H", "S.d_t", "S.ra", "S.k", "S.g"]


def _information():
    """Hᵀ H of unit-noise measurements: each scanner its own rows, the rest others."""
    rng = np.random.default_rng(3)
    rows = []
    for _ in range(500):
        for pattern in (
            {0: 1.0, 1: -0.58},  # S1: ΔΦ − cot 60° ε_H
            {2: 1.0, 3: 0.36},
        ):  # S2: ΔΦ − cot 110° ε_H
            x = np.zeros(len(NAMES))
            u = rng.normal()
            for j, c in pattern.items():
                x[j] = c * u
            rows.append(x)
        x = np.zeros(len(NAMES))
        u = rng.normal()
        x[4], x[5] = 0.01 * u, 0.01 * u + 0.001 * rng.normal()  # a weak pair, nearly one direction
        x[6] = 0.004 * rng.normal()  # weak alone
        x[7] = rng.normal()  # well determined
        rows.append(x)
    H = np.array(rows)
    return H.T @ H


def test_exact_aliases_come_apart_per_sensor():
    al = weak_directions(_information(), np.ones(len(NAMES)), NAMES, {frozenset({"S1.d_phi", "S1.eps_H"}): "declared"})
    exact = [a for a in al if a.exact]
    assert len(exact) == 2 and {frozenset(a.elements) for a in exact} == {
        frozenset({"S1.d_phi", "S1.eps_H"}),
        frozenset({"S2.d_phi", "S2.eps_H"}),
    }
    s1 = next(a for a in exact if "S1.d_phi" in a.elements)
    w = dict(zip(s1.elements, s1.weights))
    # the unseen direction is orthogonal to (1, −0.58): along (0.58, 1)/|.|
    assert abs(w["S1.d_phi"] / w["S1.eps_H"] - 0.58) < 1e-6
    assert s1.reason == "declared"


def test_near_alias_named_and_single_weak_element_left_out():
    al = weak_directions(_information(), np.ones(len(NAMES)), NAMES)
    near = [a for a in al if not a.exact]
    assert any({"S.d_t", "S.ra"} <= set(a.elements) for a in near)
    assert not any(a.elements == ("S.k",) for a in al)  # weak alone: not a combination
    assert all("S.g" not in a.elements for a in al)
    marks = set_by_prior(al, {n: 0.99 for n in NAMES}, {n: 1.0 for n in NAMES})
    assert {"S1.d_phi", "S1.eps_H", "S2.d_phi", "S2.eps_H", "S.d_t", "S.ra"} <= set(marks)
    assert "S.k" not in marks and "S.g" not in marks
    assert "exact" in marks["S1.eps_H"] and "S1.d_phi" in marks["S1.eps_H"]


def test_no_prior_elements_are_marginalized():
    A = _information()
    s0 = np.ones(len(NAMES))
    s0[7] = np.inf  # no a priori on the well-determined one
    al = weak_directions(A, s0, NAMES)
    assert all("S.g" not in a.elements for a in al)
    assert sum(a.exact for a in al) == 2
