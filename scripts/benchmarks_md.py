"""Write docs/BENCHMARKS.md from its inputs: the embedded models' cards and the result files.

    python scripts/benchmarks_md.py            # rewrite docs/BENCHMARKS.md
    python scripts/benchmarks_md.py --check    # exit 1 if the file is not what the inputs give

Inputs, nothing else (no figure is typed into this script):
- ``src/dancekit/assets/models/<name>/card.json``: each dance model's test-split figures (``"metrics"``, written
  by ``scripts/refresh_card_metrics.py`` from a ``dancekit evaluate`` report) and what the card says about them;
- ``docs/results/baselines.json``: the calibrating baselines (first column: a metric key of the cards);
- ``docs/results/*.json``: one section each, in file-name order, of the shape
  ``{"title": str, "command": str, "machine": str, "date": "YYYY-MM-DD", "columns": [str, ...],
  "rows": [[...], ...], "note": str}``.

The tests (``tests/test_benchmarks_md.py``) check that docs/BENCHMARKS.md is what this script writes from the
inputs of the checkout, and that it is at most 500 lines.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CARDS = ROOT / "src" / "dancekit" / "assets" / "models"
RESULTS = ROOT / "docs" / "results"
OUT = ROOT / "docs" / "BENCHMARKS.md"
MAX_LINES = 500

# the dance models of the quality table, in this order (folder names under CARDS)
MODELS = ("revolution", "music2dance", "dual")
# card metric key -> (row label, format); the rows of the quality table, in this order
METRICS: dict[str, tuple[str, str]] = {
    "fid_k": ("FID_k (kinetic features, lower is better)", "{:.2f}"),
    "fid_g": ("FID_g (geometric features, lower is better)", "{:.2f}"),
    "style_acc": ("style ACC (the genre read back)", "{:.3f}"),
    "style_multimodality": ("style multimodality (between seeds)", "{:.1f}"),
    "bas_bailando": ("BAS (Bailando, over music beats)", "{:.3f}"),
    "beat_coverage": ("beat coverage B_k/B_m", "{:.3f}"),
    "beat_hit_rate": ("beat hit rate B_a/B_k", "{:.3f}"),
    "stillness_share": ("stillness share (1-s windows < 10 cm/s)", "{:.4f}"),
    "smoothed_energy_ratio": ("smoothed energy / real", "{:.3f}"),
    "jitter_speed_ratio": ("jitter / real", "{:.3f}"),
    "foot_skating_ratio": ("foot skating ratio (skating / contact frames)", "{:.3f}"),
    "torso_lean_deg": ("torso lean (degrees)", "{:.1f}"),
    "beats_alignment_dual": ("beats alignment (dual learning, 0.2 s)", "{:.3f}"),
    "fd_dual_mean_joint_distance_cm": ("FD (mean joint distance to the real dance, cm)", "{:.1f}"),
}
BASELINES = "baselines.json"
RESULT_KEYS = ("title", "command", "machine", "date", "columns", "rows", "note")


class InputError(Exception):
    """A card or result file that does not have the expected shape (the message names the file)."""


def _rel(path: Path) -> str:
    """``path`` from its ``docs/`` or ``src/`` folder on (the name a maintainer knows it by)."""
    parts = path.parts
    for top in ("docs", "src"):
        if top in parts:
            return "/".join(parts[len(parts) - 1 - parts[::-1].index(top):])
    return str(path)


def read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise InputError(f"{_rel(path)}: {e}") from None
    if not isinstance(data, dict):
        raise InputError(f"{_rel(path)}: not a JSON object")
    return data


def read_result(path: Path) -> dict:
    """A result file, checked against the shape of the module docstring."""
    r = read_json(path)
    name = _rel(path)
    missing = [k for k in RESULT_KEYS if k not in r]
    if missing:
        raise InputError(f"{name}: missing {', '.join(missing)}")
    if not isinstance(r["columns"], list) or not isinstance(r["rows"], list):
        raise InputError(f"{name}: columns and rows must be lists")
    for row in r["rows"]:
        if not isinstance(row, list) or len(row) != len(r["columns"]):
            raise InputError(f"{name}: row {row!r} does not have {len(r['columns'])} cells")
    return r


def cell(value: object) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value).replace("|", "\\|")


def table(columns: list[str], rows: list[list[object]]) -> list[str]:
    out = ["| " + " | ".join(cell(c) for c in columns) + " |",
           "| --- |" + " ---: |" * (len(columns) - 1)]
    out += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return out


def command_block(command: str) -> list[str]:
    return ["```", command, "```"]


def eval_command(model: str, extra: str = "") -> str:
    return (f"dancekit evaluate --checkpoint {model} --data data/tang2018 --split test --seeds 0-4{extra} "
            f"-o runs/{model}_test")


def quality_section(cards: dict[str, dict], baselines: dict | None) -> list[str]:
    """One table: the models' test figures (cards) beside the real test dances and the baselines."""
    base_rows = {row[0]: row[1:] for row in baselines["rows"]} if baselines else {}
    base_cols = baselines["columns"][1:] if baselines else []
    keys = [k for k in METRICS if any(k in c.get("metrics", {}) for c in cards.values()) or k in base_rows]
    rows = []
    for k in keys:
        label, fmt = METRICS[k]
        vals = [fmt.format(c["metrics"][k]) if k in c.get("metrics", {}) else None for c in cards.values()]
        rows.append([label, *vals, *base_rows.get(k, [None] * len(base_cols))])
    out = ["## Quality on the test split (tang2018: 6 songs, 5 seeds each, every default stage)", "",
           "Each model's figures are its card's (`dancekit models` prints them; "
           "`src/dancekit/assets/models/NAME/card.json`); the baselines' are in `docs/results/baselines.json`. "
           "Metric definitions: docs/METRICS.md. Real dances are the bar: on FID they do not score 0.", ""]
    out += table(["metric", *(f"`{m}`" for m in cards), *base_cols], rows)
    out += ["", "Each model's column:", ""]
    out += command_block("\n".join(eval_command(m) for m in cards))
    if baselines:
        out += ["", f"The baselines' columns ({baselines['date']}; how to read them: the section "
                f"\"{baselines['title']}\" below):", ""]
        out += command_block(baselines["command"])
    return out + [""]


def model_section(name: str, card: dict) -> list[str]:
    out = [f"### `{name}`", "", card.get("description", ""), ""]
    facts = [("training data", card.get("training_data")), ("parameters", card.get("parameters")),
             ("training", card.get("training_time")), ("test figures measured", card.get("metrics_source"))]
    out += [f"- {k}: {v}" for k, v in facts if v is not None]
    steer = card.get("genre_steering")
    if isinstance(steer, dict) and "read_back" in steer:
        per = steer.get("per_genre")
        per_text = f" ({', '.join(f'{g} {v:.2f}' for g, v in per.items())})" if isinstance(per, dict) else ""
        out.append(f"- `--genre G` read back by the style classifier ({steer.get('split', 'test')}, {steer.get('n')} "
                   f"dances): {steer['read_back']:.3f}{per_text}; "
                   f"`dancekit steering --checkpoint {name} --data data/tang2018 --split test -o runs/{name}_steering.json`")
    none = card.get("metrics_genre_none")
    if isinstance(none, dict) and "fid_k" in none:
        out.append(f"- `--genre none` (the model alone): FID_k {none['fid_k']:.2f}, FID_g {none['fid_g']:.2f}; "
                   f"`{eval_command(name, ' --genre none')}`")
    comp = card.get("compose_test")
    if isinstance(comp, dict):
        out.append("- composing (`dancekit compose`, test dances): "
                   + ", ".join(f"{k.replace('_', ' ')} {v:g}" for k, v in comp.items())
                   + f"; `dancekit evaluate --compose {name} --data data/tang2018 --split test -o runs/{name}_compose`"
                   " (docs/DUAL.md)")
    curve = card.get("training_curve")
    if isinstance(curve, dict) and curve.get("rows"):
        points = []
        for row in curve["rows"]:
            fid = (f" (FID_k {row['val_fid_k']:.1f}, FID_g {row['val_fid_g']:.1f})"
                   if "val_fid_k" in row and "val_fid_g" in row else "")
            points.append(f"{row['step']}: {row['val_loss']:g}{fid}")
        out.append(f"- training curve ({curve.get('what', 'validation loss by step')}): " + "; ".join(points))
    if card.get("known_limits"):
        out.append(f"- known limits: {card['known_limits']}")
    return out + [""]


def result_section(r: dict, source: str) -> list[str]:
    out = [f"## {r['title']}", "", f"Measured {r['date']} on {r['machine']} (`{source}`).", ""]
    out += table(r["columns"], r["rows"])
    if r["note"]:
        out += ["", r["note"]]
    out += ["", "Reproduce:", ""]
    return out + command_block(r["command"]) + [""]


def render(root: Path = ROOT) -> str:
    """The text of docs/BENCHMARKS.md for the inputs under ``root``."""
    cards_dir = root / "src" / "dancekit" / "assets" / "models"
    results_dir = root / "docs" / "results"
    cards = {m: read_json(cards_dir / m / "card.json") for m in MODELS if (cards_dir / m / "card.json").exists()}
    files = sorted(results_dir.glob("*.json")) if results_dir.is_dir() else []
    results = {f.name: read_result(f) for f in files}
    lines = ["# Benchmarks", "",
             "<!-- Generated by scripts/benchmarks_md.py from the model cards and docs/results/*.json: "
             "edit those, then run `python scripts/benchmarks_md.py`. -->", "",
             "The current figures of dancekit, each with the command that reproduces it. How they were reached "
             "(the validation rounds, the rules written before each number, the alternatives tried) is in "
             "docs/research/. The data are the tang2018 dances (`dancekit prepare tang2018 ../shared/data/tang2018 "
             "-o data/tang2018`); choices were made on the validation split, the test split was scored once per "
             "shipped model.", ""]
    lines += quality_section(cards, results.get(BASELINES))
    lines += ["## The models", ""]
    for name, card in cards.items():
        lines += model_section(name, card)
    for fname, r in results.items():
        lines += result_section(r, f"docs/results/{fname}")
    return "\n".join(lines).rstrip("\n") + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare with docs/BENCHMARKS.md instead of writing it")
    args = ap.parse_args()
    try:
        text = render()
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    n = text.count("\n")
    if n > MAX_LINES:
        print(f"error: docs/BENCHMARKS.md would have {n} lines (at most {MAX_LINES})", file=sys.stderr)
        return 2
    if args.check:
        same = OUT.exists() and OUT.read_text() == text
        print("docs/BENCHMARKS.md is up to date" if same else
              "docs/BENCHMARKS.md differs from its inputs: run python scripts/benchmarks_md.py")
        return 0 if same else 1
    tmp = OUT.with_suffix(".md.tmp")
    tmp.write_text(text)
    tmp.replace(OUT)
    print(f"wrote docs/BENCHMARKS.md ({n} lines, {len(text)} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
