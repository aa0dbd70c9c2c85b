"""A blind record graded again by the verdict's rules as they are now (:func:`~jaxheli.gap.verdict.find`).

A trial's record keeps its ranking, base re-fit, structure hypothesis and re-checks, without their 40 base
parameters, which the rules do not read. A record flown under the current rules gets its own ``top`` back; one flown
under other rules shows what the current rules name on the same fits, without flying its seeds again.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ...gap.candidate_records import Entry, Refit, Structure
from ...gap.verdict import Verdict, find
from ...model import PARAM_NAMES

_NO_THETA = dict.fromkeys(PARAM_NAMES, 0.0)
"""Stands in for the base parameters a record leaves out (:func:`~._trial._untheta`)."""


def _with_theta(data: Mapping[str, Any]) -> dict[str, Any]:
    return {**data, "theta": data.get("theta", _NO_THETA)}


def _entries(record: Mapping[str, Any], key: str) -> tuple[Entry, ...]:
    return tuple(Entry.from_json(_with_theta(e)) for e in record.get(key, ()))


def regrade(record: Mapping[str, Any]) -> Verdict:
    """The verdict the current rules give a blind trial's ``record`` (one of ``blind.json``'s ``records``)."""
    structure = record.get("structure")
    return find(_entries(record, "ranking"), Refit.from_json(_with_theta(record["base_refit"])),
                None if structure is None else Structure.from_json(_with_theta(structure)), _entries(record, "recheck"),
                _entries(record, "beyond_noise"),
                {k: Entry.from_json(_with_theta(e)) for k, e in record.get("noise_beyond", {}).items()})


def regraded_top(record: Mapping[str, Any]) -> str:
    """The effect :func:`regrade` names, or ``"none"``."""
    effect = regrade(record).effect
    return "none" if effect is None else effect.effect
