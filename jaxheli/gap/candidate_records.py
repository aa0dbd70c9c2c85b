"""The records a candidate row leaves (:mod:`jaxheli.gap.candidates`): a ranking entry and its likelihood-ratio test,
the base model re-fitted alone, its structure as a hypothesis, and the named effect re-identified on both flights.

Typed inside the library; ``to_json`` / ``from_json`` for the edges only (:mod:`jaxheli.gap.records`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from ..effects.registry import Fitted
from ._record import Theta, _Flat, _named, _read, _write

@dataclasses.dataclass(frozen=True)
class LRTest(_Flat):
    """Likelihood-ratio test of a candidate against the reference on the training flight
    (:func:`~jaxheli.gap.significance.lr_test`)."""

    statistic: float
    dof: int
    p_value: float
    delta_aic: float


@dataclasses.dataclass(frozen=True)
class Entry:
    """One ranked candidate effect (or a combination ``"a+b"``), fitted on the training flight and scored on the
    validation flight (:func:`~jaxheli.gap.significance.shrink_entries`).

    Attributes:
        effect: the candidate's name.
        fitted: its fitted values with standard errors and 95 % intervals, where it acts, in words
            (:func:`~jaxheli.effects.registry.report`).
        shrink_pct: held-out shrink (%) of the reference's gap; ``shrink_se_pct`` its paired standard error (%);
            ``shrink_by_channel`` per output channel (%).
        significant: past every test of :mod:`~jaxheli.gap.significance`; ``tied_with`` the significant
            candidates within its noise.
        lr: likelihood-ratio test on the training flight; ``p_value`` the one-sided window t-test.
        gap_base, gap: the reference's and the candidate's channel-mean gap on the validation flight.
        converged: the solver's flag.
        theta: ``[40]`` base parameters fitted with the effect; ``nuisance`` the nuisance values fitted with it,
            by name (empty unless re-identified jointly).
    """

    effect: str
    fitted: Fitted
    shrink_pct: float
    shrink_se_pct: float
    shrink_by_channel: Mapping[str, float]
    significant: bool
    lr: LRTest
    p_value: float
    gap_base: float
    gap: float
    converged: bool
    theta: Theta
    nuisance: Mapping[str, float]
    tied_with: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The entry as ``jaxheli diagnose`` writes it; parameters named as in :data:`~jaxheli.PARAM_NAMES`."""
        f = self.fitted.to_json()
        return {"effect": self.effect, "where": f["where"], "params": f["params"], "shrink_pct": self.shrink_pct,
                "shrink_se_pct": self.shrink_se_pct, "shrink_by_channel": dict(self.shrink_by_channel),
                "significant": self.significant, "at_bound": f["at_bound"], "evidence_z": f["evidence_z"],
                "lr": self.lr.to_json(), "p_value": self.p_value, "gap_base": self.gap_base, "gap": self.gap,
                "summary": f["summary"], "converged": self.converged, "theta": _named(self.theta),
                "nuisance": dict(self.nuisance), "tied_with": list(self.tied_with)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Entry:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, fitted=Fitted.from_json(data), lr=LRTest.from_json(data["lr"]))


@dataclasses.dataclass(frozen=True)
class Refit:
    """The base model re-fitted alone, jointly re-identified (:func:`~jaxheli.gap.reference.base_refit`): its
    held-out shrink (%) of the given base's gap with standard error, both gaps (channel mean) and its gap per
    channel, whether the given base is ``under_fitted``, the solver's flag, ``progress_pct`` (how far its training
    RSS still fell over the candidates' budget), ``settled``, LM ``steps``, the re-fitted ``theta[40]`` and
    nuisance values; ``challenged``: a candidate's base parameters gave the reference a better basin
    (:func:`~jaxheli.gap.reference.challenge`), and ``followed``: how many candidate rows fitted better from it
    (:func:`~jaxheli.gap.reference.follow`)."""

    shrink_pct: float
    shrink_se_pct: float
    gap_base: float
    gap: float
    gap_by_channel: Mapping[str, float]
    under_fitted: bool
    converged: bool
    progress_pct: float
    settled: bool
    steps: int
    theta: Theta
    nuisance: Mapping[str, float]
    challenged: bool = False
    followed: int = 0

    def to_json(self) -> dict[str, Any]:
        """``{"joint": True, ...}`` as ``jaxheli diagnose`` writes it (a frozen base, no re-fit, writes
        ``{"joint": False}``)."""
        return {"joint": True, **_write(self)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Refit | None:
        """The inverse of :meth:`to_json` (``None`` for a frozen base; records written before the challenge's
        fields read as unchallenged)."""
        if not data["joint"]:
            return None
        return _read(cls, data, challenged=bool(data.get("challenged", False)), followed=int(data.get("followed", 0)))


@dataclasses.dataclass(frozen=True)
class Structure(_Flat):
    """The base model's structure as a hypothesis (:func:`~jaxheli.gap.structure.structure_hypothesis`): the
    reference re-fitted alone in the physical ranges, its held-out shrink (%) of the yardstick's gap with standard
    error, whether it is ``significant``, both gaps (channel mean) and its gap per channel; the pinned parameters it
    ``freed`` and those ``beyond`` the box (values by name), with the bound each ``crossed``; the re-fitted
    ``theta[40]`` and nuisance values."""

    shrink_pct: float
    shrink_se_pct: float
    significant: bool
    gap_base: float
    gap: float
    gap_by_channel: Mapping[str, float]
    freed: Mapping[str, float]
    beyond: Mapping[str, float]
    crossed: Mapping[str, float]
    theta: Theta
    nuisance: Mapping[str, float]

    @property
    def summary(self) -> str:
        """What moved, in words: ``"Nw freed (2.71), Mu beyond its bound (-0.18 past -0.1)"``."""
        moved = [f"{n} freed ({v:.3g})" for n, v in self.freed.items()]
        moved += [f"{n} beyond its bound ({v:.3g} past {self.crossed[n]:.3g})" for n, v in self.beyond.items()]
        return ", ".join(moved) or "no parameter left the box"


@dataclasses.dataclass(frozen=True)
class Final:
    """The named effect re-identified with the base model on both flights (:func:`~jaxheli.gap.final_fit.final_fit`):
    its fit, the training plus validation RSS, LM ``steps``, the base parameters ``theta[40]`` and nuisance values
    fitted with it."""

    effect: str
    fitted: Fitted
    rss: float
    steps: int
    theta: Theta
    nuisance: Mapping[str, float]

    def to_json(self) -> dict[str, Any]:
        """``{effect, params, where, summary, at_bound, evidence_z, rss, steps, theta, nuisance}``."""
        return {"effect": self.effect, **self.fitted.to_json(), **_write(self, "effect", "fitted")}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Final:
        """The inverse of :meth:`to_json`."""
        return _read(cls, data, fitted=Fitted.from_json(data))
