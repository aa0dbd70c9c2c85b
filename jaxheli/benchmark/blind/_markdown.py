"""A blind run's summary as markdown tables: one row per kind, the false-positive line, and a pair of tables per
other base method."""

from __future__ import annotations

from typing import Any

from ...gap.significance import MIN_SHRINK, MIN_Z


def markdown(summary: dict[str, Any]) -> str:
    """The summary as a markdown table (with ``"bases"``, :func:`summarise_bases`, a pair of tables per other base
    method)."""
    lines = ["| kind | trials | top-1 % | in tie % | detectable (max_k rms(y_eff - y_clean) / sigma_k > 1) | "
             "top-1 % detectable | in tie % detectable | median magnitude error (detectable) | "
             "median magnitude error (detectable, named right) | "
             "resolvable (training flight too) | top-1 % resolvable | in tie % resolvable | "
             "median magnitude error (resolvable) | "
             "beyond the structure's reach (hover re-fit leaves > sigma) | top-1 % beyond | in tie % beyond | "
             "median magnitude error (beyond) | "
             f"identifiable (oracle z >= {MIN_Z:g}) | top-1 % identifiable | in tie % identifiable | "
             "median magnitude error (identifiable) | training fit's (identifiable) | oracle's (identifiable) | "
             f"median shrink vs oracle % | base structure named % | explainable (oracle shrink >= {MIN_SHRINK:g} %) | "
             "top-1 % explainable | explainable beyond the structure | top-1 % explainable beyond the structure |",
             "|" + "---|" * 29]

    def cell(value: float | None, fmt: str) -> str:
        return "-" if value is None else format(value, fmt)

    def error(value: float | None) -> str:
        return "-" if value is None else f"{100 * value:.1f} %"

    for kind, row in summary["kinds"].items():
        subsets = "".join(f" | {row.get(f'{s}_trials', '-')} | {cell(row.get(f'top1_{s}_pct'), '.0f')}"
                          f" | {cell(row.get(f'in_tie_{s}_pct'), '.0f')}"
                          f" | {error(row.get(f'magnitude_error_median_{s}'))}"
                          + (f" | {error(row.get('magnitude_error_median_named'))}" if s == "detectable" else "")
                          for s in ("detectable", "resolvable", "beyond_structure", "identifiable"))
        lines.append(f"| {kind} | {row['trials']} | {cell(row['top1_pct'], '.0f')} | {cell(row['in_tie_pct'], '.0f')}"
                     f"{subsets} | {error(row.get('train_magnitude_error_median_identifiable'))}"
                     f" | {error(row.get('oracle_magnitude_error_median_identifiable'))}"
                     f" | {cell(row.get('shrink_vs_oracle_pct'), '.1f')} | {cell(row.get('structure_pct'), '.0f')}"
                     f" | {row.get('explainable_trials', '-')} | {cell(row.get('top1_explainable_pct'), '.0f')}"
                     f" | {row.get('explainable_beyond_structure_trials', '-')}"
                     f" | {cell(row.get('top1_explainable_beyond_structure_pct'), '.0f')} |")
    for label, pool in summary.get("forms", {}).items():
        lines.append(f"\nPooled over the {label} kinds (independent simulator): top-1 {cell(pool['top1_pct'], '.0f')} % "
                     f"of {pool['trials']} trials, {cell(pool.get('top1_resolvable_pct'), '.0f')} % of the "
                     f"{pool.get('resolvable_trials', 0)} resolvable"
                     + ("" if "resolvable_explainable_trials" not in pool else
                        f" (the oracle, the true effect fitted with the same base, shrinks the gap by {MIN_SHRINK:g} % "
                        f"or more on {pool['resolvable_explainable_trials']} of them, top-1 "
                        f"{cell(pool.get('top1_resolvable_explainable_pct'), '.0f')} % there)")
                     + ("" if "beyond_structure_trials" not in pool else
                        f", {cell(pool.get('top1_beyond_structure_pct'), '.0f')} % of the "
                        f"{pool['beyond_structure_trials']} beyond the structure's reach"))
    ci = summary.get("false_positive_ci95_pct")
    lines.append(f"\nFalse positives on effect-free flights: {cell(summary['false_positive_pct'], '.0f')} %"
                 + (f" ({summary['false_positives']} of {summary['controls']}; 95 % Wilson interval "
                    f"{ci[0]:.0f}-{ci[1]:.0f} %)" if ci else ""))
    for method, both in summary.get("bases", {}).items():
        main = summary.get("base", "pem")
        lines.append(f"\n### Base model by {method} against {main}, on the same trials (seeds {both['seeds']})\n")
        lines += [f"{m}:\n\n{markdown(both[m])}\n" for m in (method, main)]
    return "\n".join(lines)
