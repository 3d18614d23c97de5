"""What the numbers on the screens mean: one entry per term, shown by the help screen (``?``)
and quoted in the README. Plain text, no Textual."""

from __future__ import annotations

from gcs_core.diagnosis.ranking import RULE

#: (term, what it means and how to read it)
TERMS: tuple[tuple[str, str], ...] = (
    (
        "normalized RMS",
        "RMS of a sensor's residuals divided by its noise σ. 1.0 is the noise floor: the model "
        "explains everything but noise. Above 1.05 (red) something is missing or the noise is "
        "understated; well below 1 the data-book noise is pessimistic.",
    ),
    (
        "held-out RMS",
        "The same on a span left out of the fit. If the fitted RMS falls but the held-out one does "
        "not, the added effect fitted noise (over-fitting).",
    ),
    (
        "Δχ²",
        "How much χ² (the sum of squared normalized residuals) would fall if the candidate effect were "
        "added and the fit repeated: the score test at the current solution, no refit.",
    ),
    (
        "p",
        "The chance of a Δχ² at least this large on its degrees of freedom if the effect were absent "
        "(χ² distribution). Small p: the data show the signature. Shown as < 1e-16 below double precision.",
    ),
    (
        "p adj",
        "p corrected for trying many candidates (Bonferroni): p adj = min(1, m·p) for m candidates. This is "
        "the number compared with α.",
    ),
    (
        "α (significance)",
        "The family-wise level (config diagnosis.significance): the chance that any one of the "
        "candidates looks significant by noise alone. Significant means p adj < α.",
    ),
    ("ranking", RULE),
    (
        "id? (identifiable)",
        "Whether the data can tell the effect apart from what is already estimated and from "
        "the other candidates. 'no': adding it would trade off against its aliases and its "
        "estimate would come from the a priori.",
    ),
    (
        "aliases",
        "The elements in the state (or other candidates, with their canonical correlation ρ) whose "
        "signature the candidate's resembles; ρ near 1 means indistinguishable with these data.",
    ),
    (
        "MDB",
        "Minimal detectable bias: the smallest size of the effect this test would detect 80 % of the time "
        "at level α. An estimate well below its MDB is not evidence of absence.",
    ),
    (
        "estimate ± σ",
        "The fitted value and its 1-σ uncertainty. The unit is chosen from σ (arcsec below 1°, "
        "deg above; rates in deg/h, from 1°/s in deg/s) and σ keeps two significant digits, the value "
        "rounded to match.",
    ),
    (
        "not determined (dim)",
        "An element whose σ says it is known but which the data did not determine (seen "
        "only through another element consistent with zero); do not trust its σ.",
    ),
    (
        "unobservable",
        "The data constrain only a combination of the elements named, not each one; their σ there "
        "comes from the a priori, not from the data.",
    ),
    (
        "NIS and its band",
        "Normalized innovation squared of a Kalman block divided by its degrees of freedom: "
        "about 1 when the filter's predicted uncertainty matches the data. The band is the 95 % "
        "χ² range for that block; blocks outside it (more than 1 in 20) mean the noise model "
        "or the state is wrong.",
    ),
    (
        "passes",
        "The Kalman method filters and smooths the data, then may repeat about the smoothed estimate "
        "(max_passes); stopping at the set number is normal, 'converged' means the last pass changed "
        "nothing that matters.",
    ),
    (
        "§4.4 σ",
        "Verification: the RMS about zero of onboard − ground attitude per axis (seed §4.4). The flag "
        "is set when it exceeds both the ground solution's accuracy and the requirement.",
    ),
)
