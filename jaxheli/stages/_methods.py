"""The named methods as chains of stages, and the one table that maps :func:`jaxheli.identify`'s option keywords
onto the stages that use them (an option no stage of the chain uses is refused, naming the methods that use it)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from ._frequency import FrequencyFit
from ._pem import PEM
from ._polish import Polish
from ._search import Search
from ._stage import Stage, check_chain
from ._structure import Structure

CHAINS: dict[str, tuple[Stage, ...]] = {
    "iwo": (Search(),),
    "ga": (Search(engine="ga"),),
    "pem": (PEM(),),
    "iwo+polish": (Search(), Polish()),
    "freq": (FrequencyFit(),),
    "freq+polish": (FrequencyFit(), Polish()),
    "iwo+freq+polish": (Search(), FrequencyFit(), Polish()),
}
"""Each method's chain, its stages at their defaults. ``iwo+freq+polish``: IWO's best of each trial starts the
frequency fit beside the fit's screened draws, and the polish's first round tries the lowest J and IWO's best
(IWO alone can settle where the rotor and stabilizer-bar time constants trade places; the frequency fit alone, from
the box's draws, in a minimum of J with a coupling of the wrong sign)."""

METHODS: tuple[str, ...] = tuple(CHAINS)

_EVERY = (Stage,)

KEYWORDS: dict[str, tuple[tuple[type[Stage], ...], Any]] = {
    "outputs": (_EVERY, None),
    "segment": (_EVERY, None),
    "hold": (_EVERY, None),
    "g": (_EVERY, None),
    "lower": (_EVERY, None),
    "upper": (_EVERY, None),
    "cost": ((Search, Polish), None),
    "search_precision": ((Search,), None),
    "iterations": ((Search,), "iterations"),
    "engine_options": ((Search,), "options"),
    "chunk": ((Search,), "chunk"),
    "checkpoint": ((Search,), "checkpoint"),
    "resume": ((Search,), "resume"),
    "progress": ((Search,), "progress"),
    "start": ((PEM, FrequencyFit), "start"),
    "pem_segment": ((PEM,), "segment"),
    "freq_options": ((FrequencyFit,), "options"),
    "polish_objective": ((Polish,), "objective"),
    "polish_steps": ((Polish,), "steps"),
    "polish_rounds": ((Polish,), "rounds"),
    "cv_windows": ((Polish,), "cv_windows"),
    "prior": ((PEM, Polish), "prior"),
    "prior_sd": ((PEM, Polish), "prior_sd"),
    "structure": ((PEM, Polish), Structure),
}
"""identify's option keywords: the stages that use each, and what it sets: a field of theirs, a setting of the
problem (``None``; ``cost`` is what the search minimises and the polish reports, ``search_precision`` the
search's arithmetic), or ``Structure`` (``structure=True`` wraps the chain's last stage). ``start`` is the first
stage's only: a later one starts from the trials before it."""


def _users(chain: tuple[Stage, ...], keyword: str) -> list[int]:
    """Indices of ``chain``'s stages that use ``keyword`` (a structure determination's: its fit's)."""
    kinds, target = KEYWORDS[keyword]
    last = len(chain) - 1 if target is Structure else None
    fits = [s.fit if isinstance(s, Structure) else s for s in chain]
    return [i for i, s in enumerate(fits) if isinstance(s, kinds) and (keyword != "start" or i == 0)
            and (last is None or i == last)]


def uses(method: str, keyword: str) -> bool:
    """Whether ``method``'s chain uses the option ``keyword``."""
    return bool(_users(CHAINS[method], keyword))


def used_by(keyword: str) -> str:
    """The named methods that use the option ``keyword``, for messages (``"iwo, ga, ..."``)."""
    return ", ".join(m for m in METHODS if uses(m, keyword))


def method_chain(method: str | Sequence[Stage], options: dict[str, Any]) -> tuple[str, tuple[Stage, ...]]:
    """The name and the chain of ``method`` (a named method, or stages), with ``options`` (identify's keywords; for
    a chain of stages, the problem's settings only) set on the stages that use them. An option that no stage of
    the chain uses is a one-line ``ValueError`` naming the methods that do; an unknown one a ``TypeError``."""
    named = isinstance(method, str)
    if named and method not in CHAINS:
        raise ValueError(f"identify: method must be one of {METHODS}, got {method!r}")
    chain = CHAINS[method] if named else check_chain(method)
    name = method if named else "+".join(stage.name for stage in chain)
    fields: list[dict[str, Any]] = [{} for _ in chain]
    for keyword, value in options.items():
        if keyword not in KEYWORDS:
            raise TypeError(f"identify: unknown option {keyword!r}; options are {', '.join(KEYWORDS)}")
        target = KEYWORDS[keyword][1]
        if not named and target is not None:
            raise ValueError(f"identify: {keyword!r} is a named method's option; set it on the chain's stage")
        users = _users(chain, keyword)
        if not users:
            raise ValueError(f"identify: method {name!r} does not use {keyword!r} (used by: {used_by(keyword)})")
        for i in users:
            if isinstance(target, str):
                fields[i][target] = value
    stages = [dataclasses.replace(stage, **given) if given else stage for stage, given in zip(chain, fields)]
    if options.get("structure"):
        stages[-1] = Structure(stages[-1])
    return name, check_chain(stages)
