"""Report tables: the markdown of one ``dancekit evaluate`` report and side-by-side comparisons.

A report is the dict of :func:`dancekit.evaluation.evaluate_dirs` / :func:`~dancekit.evaluation.evaluate_motions`
(``metrics``, ``real``, ``counts``, ``settings``, ``notes``, ...). :data:`TABLE_ROWS` names the metrics
the tables show, in order, with their labels and number formats.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from dancekit.errors import ParameterError

__all__ = ["TABLE_ROWS", "format_comparison", "format_markdown", "format_value", "metrics_table"]

#: (key, label, format) rows of the markdown table, in order.
TABLE_ROWS: tuple[tuple[str, str, str], ...] = (
    ("fid_k", "FID_k (AIST++)", "{:.2f}"),
    ("fid_g", "FID_g (AIST++)", "{:.2f}"),
    ("div_k", "Div_k", "{:.2f}"),
    ("div_g", "Div_g", "{:.2f}"),
    ("bas_bailando", "BAS (Bailando, over music beats)", "{:.4f}"),
    ("bas_aist", "BAS (AIST++, over kinematic beats)", "{:.4f}"),
    ("beat_coverage", "Beat coverage B_k/B_m", "{:.3f}"),
    ("beat_hit_rate", "Beat hit rate B_a/B_k", "{:.3f}"),
    ("beats_alignment_dual", "Beats alignment (dual-learning, 0.2 s)", "{:.3f}"),
    ("style_fid", "FID (style classifier)", "{:.2f}"),
    ("style_acc", "ACC (style)", "{:.3f}"),
    ("style_diversity", "Diversity (style features)", "{:.2f}"),
    ("style_multimodality", "Multimodality (style features)", "{:.2f}"),
    ("fd_dual_mean_joint_distance_cm", "FD (dual-learning, mean joint distance, cm)", "{:.1f}"),
    ("freeze_score", "Freeze score (energy last/first 10 s)", "{:.3f}"),
    ("stillness_share", "Stillness share (1 s windows < 10 cm/s)", "{:.3f}"),
    ("smoothed_energy", "Smoothed energy (m/s)", "{:.3f}"),
    ("smoothed_energy_ratio", "Smoothed energy / real", "{:.3f}"),
    ("jitter_speed", "Jitter (speed removed by 5-frame average, m/s)", "{:.4f}"),
    ("jitter_speed_ratio", "Jitter / real", "{:.3f}"),
    ("jerk", "Mean jerk (m/s³)", "{:.1f}"),
    ("jerk_ratio", "Jerk / real", "{:.3f}"),
    ("foot_skating_ratio", "Foot skating ratio", "{:.3f}"),
    ("foot_skating_ratio_ratio", "Foot skating / real", "{:.3f}"),
    ("pfc", "PFC (EDGE)", "{:.3f}"),
    ("bone_length_variation", "Bone-length variation (std/mean)", "{:.4f}"),
    ("ground_penetration_m", "Ground penetration (mean depth, m)", "{:.4f}"),
    ("torso_lean_deg", "Torso lean from vertical (median, degrees)", "{:.1f}"),
)


def format_value(value: Any, fmt: str, *, signed_zero: bool = False) -> str:
    """One table cell: ``fmt.format(value)``, "–" for a missing or non-finite value, and no "-0.000"
    (a negative number that rounds to zero is written without its sign) unless ``signed_zero``."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    text = fmt.format(value)
    if signed_zero:
        return text
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def format_markdown(report: Mapping[str, Any], *, title: str | None = None) -> str:
    """The report as a markdown table: metric | generated | real."""
    lines = []
    if title:
        lines += [f"### {title}", ""]
    lines += ["| metric | generated | real |", "| --- | ---: | ---: |"]
    for key, label, fmt in TABLE_ROWS:
        g = report["metrics"].get(key)
        r = report["real"].get(key)
        if g is None and r is None:
            continue
        lines.append(f"| {label} | {format_value(g, fmt)} | {format_value(r, fmt)} |")
    c = report["counts"]
    lines += ["", f"{c['generated_files']} generated dances for {c['songs']} songs; "
              f"FID reference: {report['settings']['fid_reference']} ({c['fid_reference_dances']} dances)."]
    for note in report.get("notes", []):
        lines.append(f"- {note}")
    return "\n".join(lines) + "\n"


def metrics_table(columns: Sequence[tuple[str, Mapping[str, Any]]], *, signed_zero: bool = False) -> str:
    """A markdown table with one column per ``(name, metrics)`` pair and one row per :data:`TABLE_ROWS`
    metric that some column has (no trailing newline)."""
    lines = ["| metric | " + " | ".join(name for name, _ in columns) + " |",
             "| --- |" + " ---: |" * len(columns)]
    for key, label, fmt in TABLE_ROWS:
        values = [metrics.get(key) for _, metrics in columns]
        if all(v is None for v in values):
            continue
        lines.append(f"| {label} | " + " | ".join(format_value(v, fmt, signed_zero=signed_zero) for v in values)
                     + " |")
    return "\n".join(lines)


def format_comparison(reports: Sequence[tuple[str, Mapping[str, Any]]]) -> str:
    """Side-by-side table of several reports: the real dances of the first report, then each report's
    generated dances (no trailing newline).

    Negative values that round to zero keep their sign here ("-0.000"), as in the comparison tables
    published in ``docs/BENCHMARKS.md``.
    """
    if not reports:
        raise ParameterError("no reports to compare")
    columns = [("real (test)", reports[0][1]["real"])] + [(name, r["metrics"]) for name, r in reports]
    return metrics_table(columns, signed_zero=True)
