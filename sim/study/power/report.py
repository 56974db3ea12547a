"""What `power` tells: its table, its JSON (the rows other tools read) and the power curve."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sim.study.analysis.contrasts import MEASURES
from sim.study.power.sample_size import PowerQuestion, PowerRow, needed

__all__ = ["TARGETS", "power_data", "power_table", "plot_power"]

TARGETS = (0.8, 0.9)


def _binomial_half_width(p: float, k: int) -> float:
    """The 95 % half-width of a simulated probability (normal approximation)."""
    return 1.96 * math.sqrt(max(p * (1.0 - p), 0.25 / k) / k)


def power_data(question: PowerQuestion, rows: Sequence[PowerRow], seconds: float) -> dict[str, Any]:
    return {
        "test": question.test,
        "measure": MEASURES[question.test],
        "difference": question.difference,
        "sd_between": question.sd_between,
        "sesoi": question.sesoi,
        "simulations": question.simulations,
        "seed": question.seed,
        "rows": [
            {
                "participants": row.participants,
                "p_different": row.p_different,
                "p_equivalent": row.p_equivalent,
                "slope_dropped": row.slope_dropped,
            }
            for row in rows
        ],
        "needed": {
            verdict: {f"{target:g}": needed(rows, target, verdict) for target in TARGETS}
            for verdict in ("equivalent", "different")
        },
        "seconds": round(seconds, 1),
    }


def power_table(question: PowerQuestion, rows: Sequence[PowerRow]) -> str:
    """The Markdown table and the N needed for 80 % and 90 %."""
    k = question.simulations
    lines = [
        f"Test {question.test} ({MEASURES[question.test]}): true VR − reality {question.difference:+g}, SD between "
        f"participants {question.sd_between:g}, SESOI ±{question.sesoi:g}; {k} simulated studies per N "
        f"(each probability ± {_binomial_half_width(0.5, k):.3f} at most, 95 %).",
        "",
        "| participants | P(equivalent) | P(different) | fits without the random slope |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {row.participants} | {row.p_equivalent:.3f} | {row.p_different:.3f} | {row.slope_dropped:.1%} |"
        for row in rows
    ]
    lines.append("")
    for verdict in ("equivalent", "different"):
        for target in TARGETS:
            n = needed(rows, target, verdict)
            found = f"{n} participants" if n is not None else f"more than {max(r.participants for r in rows)}"
            lines.append(f'- "{verdict}" with probability {target:.0%}: {found}')
    return "\n".join(lines) + "\n"


def plot_power(question: PowerQuestion, rows: Sequence[PowerRow], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = question.simulations
    figure, axes = plt.subplots(figsize=(7, 4.5))
    sizes = [row.participants for row in rows]
    for label, values, colour in (
        ("equivalent (90 % CI inside ±SESOI)", [row.p_equivalent for row in rows], "tab:green"),
        ("different (95 % CI excludes 0)", [row.p_different for row in rows], "tab:red"),
    ):
        errors = [_binomial_half_width(p, k) for p in values]
        axes.errorbar(sizes, values, yerr=errors, marker="o", capsize=3, color=colour, label=label)
    for target in TARGETS:
        axes.axhline(target, color="grey", linestyle=":", linewidth=1)
    axes.axhline(0.05, color="grey", linestyle="--", linewidth=1, label="5 %")
    axes.set(
        xlabel="participants",
        ylabel="probability of the verdict",
        ylim=(-0.02, 1.02),
        title=(
            f"Test {question.test}: true difference {question.difference:+g}, SD {question.sd_between:g}, "
            f"SESOI ±{question.sesoi:g}"
        ),
    )
    axes.legend(loc="best")
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
