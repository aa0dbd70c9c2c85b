"""Whether a candidate effect is significant: its held-out shrink over the reference, the noise floor, paired
standard errors, ties, and the likelihood-ratio test beside them.

A candidate is significant when its held-out shrink over the reference is at least ``min_shrink`` % (the noise
floor, :data:`MIN_SHRINK` by default) and at least :data:`EFFECT_SIGMA` of its own standard error (windows of the
validation flight paired, :func:`paired_se`) unless it is :data:`LARGE_SHRINK` or more; when no fitted parameter
sits on its physical bound (:func:`jaxheli.effects.registry.at_bound`: a 0.5 s "input delay" has absorbed something
else); and when its fitted size lies :data:`MIN_Z` standard errors or more from no effect or, where it does not, its
held-out shrink stands :data:`HELD_OUT_SIGMA` standard errors above zero (:func:`evident`). Below the floor, a
candidate is significant when its likelihood-ratio test on the training flight is past :data:`LR_P` and its held-out
shrink stands :data:`EFFECT_SIGMA` standard errors above zero (:func:`lr_evident`). Two significant candidates whose
shrinks differ by less than :data:`TIE_SIGMA` standard errors of their paired difference are a tie (``tied_with``;
e.g. a delay and a first-order lag at low frequency): the verdict names the set.

Each entry carries that likelihood-ratio test (``lr``: ``n_eff ln(RSS_ref / RSS)`` against chi-squared with as many
degrees of freedom as effect parameters the fit resolved, and the AIC difference) and ``p_value``, a one-sided t-test
over 0.5 s validation windows of the log ratio of reference to candidate residual energy, which is not part of the
verdict: an effect that acts only at large inputs (saturation, drag) concentrates its gain in a few windows, and
window tests then miss large shrinks of real effects."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
import scipy.stats

from .._types import Float
from ..effects import registry as fx
from .fit_effect import EffectFit, fitted_nuisance
from .thresholds import THRESHOLDS
from .candidate_records import Entry, LRTest

MIN_SHRINK = THRESHOLDS.min_shrink
"""(Every value here is read from the thresholds file, :mod:`jaxheli.gap.thresholds`, which records how it was
set.) Default noise floor (% of the reference's validation gap): the smallest held-out shrink that can be
significant; the blind check calls an effect explainable from an oracle shrink of this floor."""

MIN_Z = THRESHOLDS.min_z
"""Smallest distance of a significant effect from no effect, in standard errors of its fitted size
(:func:`~jaxheli.effects.registry.evidence`): a shrink bought by parameters indistinguishable from zero (a
"2 +- 3 ms delay") is model error the fit absorbed, not the effect."""

SIG_SIGMA = THRESHOLDS.sig_sigma
"""Standard errors (paired over validation windows) the base model's own re-fits must shrink the gap by (the
reference: under-fitted; the structure hypothesis): a one-sided 5 % test."""

EFFECT_SIGMA = THRESHOLDS.effect_sigma
"""Standard errors (paired over validation windows) a candidate effect's shrink below :data:`LARGE_SHRINK` must
stand above zero to be significant (one-sided 2.3 %)."""

LARGE_SHRINK = THRESHOLDS.large_shrink
"""Held-out shrink (%) that is significant without the window test: an effect that acts only in large
manoeuvres (saturation, a long delay) concentrates its shrink in their few windows, so its window standard
error is large even when the effect is real."""

HELD_OUT_SIGMA = THRESHOLDS.held_out_sigma
"""Standard errors (paired over validation windows) by which a candidate's held-out shrink must stand above zero to
be evidence of its effect in place of its fitted size's distance from no effect (:data:`MIN_Z`): that distance is a
Wald statistic, and where the size's influence saturates it says nothing. A gust's standard deviation, once the
restart filter follows the wind, moves the predictions little either way."""

LR_P = THRESHOLDS.lr_p
"""Largest p-value of a candidate's likelihood-ratio test on the training flight (:func:`lr_test`) that is evidence
of its effect below the noise floor (:func:`lr_evident`), its held-out shrink confirmed by the window test. A
small effect that a re-fitted base model nearly absorbs (a fast servo read as the flapping lag) explains the training
flight clearly yet shrinks the validation gap by less than :data:`MIN_SHRINK`. Only for effects that leave the
restart filter alone: fitting the gust or the bias walk whitens the residuals, so their statistics are large on
effect-free flights too."""

TIE_SIGMA = THRESHOLDS.tie_sigma
"""Standard errors (paired over validation windows) by which two candidates' shrinks must differ not to be a
tie."""


class HeldOut(NamedTuple):
    """Scores of one or more models on the validation flight: gap per channel (:func:`jaxheli.cost.nmse`) and
    residual energy per significance window (:meth:`~jaxheli.gap.predictor.Predictor.segment_energy`)."""

    gap: Float[np.ndarray, "*R k"]
    energy: Float[np.ndarray, "*R S"]

    def take(self, rows: int | slice | np.ndarray) -> HeldOut:
        """The scores of ``rows``."""
        return HeldOut(self.gap[rows], self.energy[rows])


def paired_se(seg_a: np.ndarray, seg_b: np.ndarray, total: float) -> float:
    """Standard error (%) of ``100 (sum seg_a - sum seg_b) / total``, the windows taken as paired samples."""
    d = np.asarray(seg_a, np.float64) - np.asarray(seg_b, np.float64)
    return float(100.0 * np.sqrt(d.size) * np.std(d, ddof=1) / total) if d.size > 1 else float("inf")


def evident(z: float, shrink: float, se: float) -> bool:
    """Whether a candidate is evidence of its effect: its fitted size ``z`` standard errors from no effect
    (:data:`MIN_Z`), or its held-out ``shrink`` (%) :data:`HELD_OUT_SIGMA` times its paired standard error ``se`` (%)
    or more."""
    return bool(z >= MIN_Z or shrink >= HELD_OUT_SIGMA * se)


def lr_evident(effect: str, lr: LRTest, shrink: float, se: float) -> bool:
    """Whether a candidate is evidence of its effect by its training flight's likelihood ratio below the noise
    floor: ``effect`` does not change the restart filter (:func:`jaxheli.effects.registry.filtered`), its
    likelihood-ratio p-value (``lr``) is :data:`LR_P` or less, and its held-out ``shrink`` (%) stands
    :data:`EFFECT_SIGMA` times its paired standard error ``se`` (%) above zero."""
    return bool(not fx.filtered(effect) and lr.p_value <= LR_P and shrink > 0 and shrink >= EFFECT_SIGMA * se)


def lr_test(rss_ref: float, rss: float, n_eff: float, dof: int) -> LRTest:
    """Likelihood-ratio test of a candidate against the reference on the training flight (Gaussian errors,
    variance profiled out): ``statistic = n_eff ln(RSS_ref / RSS)``, ``p_value`` of chi-squared with ``dof``
    degrees of freedom, ``delta_aic = 2 dof - statistic`` (negative favours the candidate)."""
    stat = float(n_eff * np.log(rss_ref / rss)) if rss > 0 and rss_ref > 0 else 0.0
    p = float(scipy.stats.chi2.sf(max(stat, 0.0), dof)) if dof > 0 else 1.0
    return LRTest(stat, int(dof), p, 2.0 * dof - stat)


def shrink_entries(
    names: list[str], outputs: tuple[str, ...], fit: EffectFit, held: HeldOut, min_shrink: float, shared: bool = False,
) -> list[Entry]:
    """Ranking entries of the candidates ``names``, best first (``theta``: the base parameters fitted with the
    effect; ``nuisance``: the nuisance values fitted with it, by name, when ``shared``: the fits freed them in their
    trailing columns, :func:`~jaxheli.gap.fit_effect.with_reference`).

    Row 0 of ``fit`` (training) and of ``held`` (validation, ``[1 + C]`` rows) is the reference; row ``c + 1`` the
    candidate ``names[c]``.
    """
    gap_ref, seg_ref = np.asarray(held.gap[0]), np.asarray(held.energy[0])
    total_ref, energy = float(np.mean(gap_ref)), float(np.sum(seg_ref))
    out = []
    for c, name in enumerate(names, start=1):
        value = np.asarray(fit.z[c])
        fitted = fx.report(name, outputs, value, np.asarray(fit.stderr[c]))
        shrink = 100.0 * (total_ref - float(np.mean(held.gap[c]))) / total_ref
        se = paired_se(seg_ref, held.energy[c], energy)
        d = np.log(seg_ref) - np.log(held.energy[c])
        p_value = float(scipy.stats.ttest_1samp(d, 0.0, alternative="greater").pvalue) if np.ptp(d) > 0 else 1.0
        lr = lr_test(float(fit.rss[0]), float(fit.rss[c]), float(fit.n_eff[c]), int(fit.k_active[c] - fit.k_active[0]))
        out.append(Entry(
            effect=name,
            fitted=fitted,
            shrink_pct=shrink,
            shrink_se_pct=se,
            shrink_by_channel={ch: 100.0 * float((gb - g) / gb) for ch, gb, g in zip(outputs, gap_ref, held.gap[c])},
            significant=bool(not fitted.at_bound and (
                (shrink >= min_shrink and (shrink >= EFFECT_SIGMA * se or shrink >= LARGE_SHRINK)
                 and evident(fitted.evidence_z, shrink, se)) or lr_evident(name, lr, shrink, se))),
            lr=lr,
            p_value=p_value,
            gap_base=total_ref,
            gap=float(np.mean(held.gap[c])),
            converged=bool(fit.converged[c]),
            theta=np.asarray(fit.theta[c], np.float64),
            nuisance=fitted_nuisance(value, outputs, fitted.params) if shared else {},
        ))
    tied = [tuple(o.effect for j, o in enumerate(out) if j != i and e.significant and o.significant
                  and abs(e.shrink_pct - o.shrink_pct) < TIE_SIGMA * paired_se(held.energy[i + 1],
                                                                                held.energy[j + 1], energy))
            for i, e in enumerate(out)]
    return sorted((dataclasses.replace(e, tied_with=t) for e, t in zip(out, tied)), key=lambda e: -e.shrink_pct)


def yardstick(given: HeldOut, rows: HeldOut) -> HeldOut:
    """``rows`` (row 0 the reference, then the candidates; :func:`~jaxheli.gap.ranking.fit_and_score`) with the
    reference replaced by the ``given`` base when that predicts the validation flight better: candidates are
    credited only beyond the better of the two models without an effect. A re-fit of the base alone can over-fit
    the training flight; against it, any candidate that merely stays near the given base is credited."""
    if float(np.mean(given.gap)) >= float(np.mean(rows.gap[0])):
        return rows
    gap, energy = np.array(rows.gap), np.array(rows.energy)
    gap[0], energy[0] = given.gap, given.energy
    return HeldOut(gap, energy)
