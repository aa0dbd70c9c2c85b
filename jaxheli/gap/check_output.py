"""The consistency check's files: ``consistency.json`` and the kinematic comparison plot."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..data.flight import FlightData
from ._finding import Finding
from .correction import correct
from .detectors.kinematics import kinematic_terms


def plot_kinematics(flight: FlightData, corrected: FlightData, path: str | Path) -> Path:
    """PNG of the kinematic comparison per axis: d(angle)/dt against the rate-implied ``c rate + e``, before
    and after :func:`correct` (signals low-passed as in the check)."""
    from ..plots import _save, _subplots

    columns = (("recorded", flight), ("corrected", corrected))
    terms = [kinematic_terms(f)[1] for _, f in columns]
    keys = list(terms[0]) or [("none", "-", "-")]
    fig, axes = _subplots(len(keys), 2, figsize=(13, 2.4 * len(keys) + 0.6), sharex="col", squeeze=False)
    for row, key in enumerate(keys):
        for (label, f), term, ax in zip(columns, terms, axes[row]):
            if key in term:
                ang, rate, c, e = term[key]
                ax.plot(f.time, np.gradient(ang, f.dt), color="black", lw=0.9, label=f"d{key[1]}/dt")
                ax.plot(f.time, c * rate + e, lw=0.8, label=f"from {key[2]} (Euler kinematics)")
                ax.legend(loc="upper right", fontsize=8, ncol=2)
            ax.set_title(f"{key[0]}, {label}", fontsize=9)
            ax.set_ylabel("rad/s")
            ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("time [s]")
    fig.suptitle(f"Kinematic consistency: {flight.source}", fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def write_check(flight: FlightData, findings: list[Finding], out: str | Path) -> list[Path]:
    """Write ``consistency.json`` (the findings' :meth:`Finding.to_json`) and ``consistency.png``
    (:func:`plot_kinematics` of ``flight`` before and after :func:`correct`) into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "consistency.json"
    path.write_text(json.dumps([f.to_json() for f in findings], indent=2))
    return [path, plot_kinematics(flight, correct(flight, findings), out / "consistency.png")]
