"""Embed a trained checkpoint as a default model of the package (``dancekit/assets/models/NAME``).

    python scripts/embed_model.py runs/revolution/best --name revolution \
        --report runs/revolution/eval/report.json --training-time "34 min on 2 CPU cores" \
        --description "Dance Revolution, 3D tang2018 skeleton, linear curriculum"

Copies ``config.json``, ``model.safetensors`` and ``stats.npz`` (nothing else) and writes
``card.json``: description, training data (from the checkpoint), parameter count, training time
(given), and the test-split metrics from a ``dancekit evaluate`` report. Refuses files over 20 MB.
``--half`` stores the weights as float16 (the loader upcasts to float32); ``--extra JSON`` merges a JSON
object into the card (e.g. the dual model's composing scores).

``--genre-model GENRE=DIR`` (repeatable) adds a genre model (e.g. the model fine-tuned on one genre's
dances) as ``genres/GENRE/``, its weights stored as float16 (half the size; the pipeline computes in
float32); ``--genre-report JSON`` records the genre-steering scores of ``dancekit steering``.
``--music-attributes DIR`` adds a music attribute classifier (``dancekit train music_attributes``) as
``music_attributes/``: ``--genre auto`` then reads the genre from the music and dances it with the genre
model. ``--report`` is then the report of that default behaviour; ``--report-none JSON`` adds the report
of the model alone (``--genre none``) to the card. The parts are declared in the model's ``config.json``
(``"components": {"genre_reader": "music_attributes", "genres": {"waltz": "genres/waltz", ...}}``,
:func:`dancekit.checkpoints.declare_components`), which is how the pipeline finds them.

``--float16`` stores the model's own weights as float16 too (the loader copies them into float32
parameters); ``--foot-constraint DIR`` adds a Foot Constraint Model (``dancekit train foot_constraint``) as
``foot_constraint/`` (float16), declared as the ``"foot_constraint"`` component that ``dancekit dance
--foot-constraint`` uses; ``--temperature T`` records the default sampling temperature of a Music2Dance
model (``"sampling": {"temperature": T}`` in its config.json); ``--card JSON`` merges more entries into the card.

A classifier is embedded the same way (e.g. the style classifier of ``dancekit evaluate``:
``python scripts/embed_model.py runs/style/best --name style --description ... --scores scores.json``,
with the scores of ``dancekit score-classifier runs/style/best --data DIR -o scores.json`` in the card).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "src" / "dancekit" / "assets" / "models"
KEEP = ("config.json", "model.safetensors", "stats.npz")
CARD_METRICS = (  # keys of a report's "metrics"
    "fid_k", "fid_g", "style_acc", "bas_bailando", "beat_coverage", "beat_hit_rate",
    "stillness_share", "smoothed_energy_ratio", "jitter_speed_ratio", "foot_skating_ratio",
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint")
    parser.add_argument("--name", required=True)
    parser.add_argument("--description", required=True)
    parser.add_argument("--report", default=None, help="dancekit evaluate report.json (test split)")
    parser.add_argument("--training-time", default=None, help="e.g. '34 min on 2 CPU cores'")
    parser.add_argument("--genre-model", action="append", default=[], metavar="GENRE=DIR",
                        help="add a genre model (float16 weights) as genres/GENRE")
    parser.add_argument("--genre-training", default=None, help="how the genre models were trained (card)")
    parser.add_argument("--genre-report", default=None, help="genre steering report (dancekit steering -o)")
    parser.add_argument("--music-attributes", default=None, metavar="DIR",
                        help="add a music attribute classifier checkpoint as music_attributes/")
    parser.add_argument("--music-attributes-training", default=None,
                        help="how the music attribute classifier was trained and how it scores (card)")
    parser.add_argument("--report-none", default=None, metavar="JSON",
                        help="dancekit evaluate report of the model alone (--genre none, test split)")
    parser.add_argument("--scores", default=None, metavar="JSON",
                        help="a classifier's scores (dancekit score-classifier -o) for the card")
    parser.add_argument("--float16", "--half", action="store_true",
                        help="store the weights as float16 (half the size; the loader upcasts to float32)")
    parser.add_argument("--foot-constraint", default=None, metavar="DIR",
                        help="add a Foot Constraint Model checkpoint (float16) as foot_constraint/")
    parser.add_argument("--temperature", type=float, default=None,
                        help="default sampling temperature (Music2Dance), recorded in config.json")
    parser.add_argument("--card", "--extra", default=None, metavar="JSON",
                        help="a JSON object merged into the card (e.g. a family's own measurements)")
    parser.add_argument("--meta", action="append", default=[], metavar="KEY=JSON",
                        help="set a top-level entry of the embedded config.json (e.g. a pipeline setting "
                             "chosen on validation: smooth_frames=9)")
    args = parser.parse_args(argv)

    from dancekit.checkpoints import declare_components

    src = Path(args.checkpoint)
    config = json.loads((src / "config.json").read_text())
    for name in KEEP:
        if (src / name).stat().st_size > 20e6:
            print(f"embed_model: {src / name} is over 20 MB", file=sys.stderr)
            return 2
    dst = MODELS / args.name
    if dst.exists():
        shutil.rmtree(dst)
    _copy_checkpoint(src, dst, weights=not args.float16)
    if args.float16:
        _half_weights(src, dst)
    meta = {f"{k}": v for k, v in (_meta_item(item) for item in args.meta)}
    if args.temperature is not None:
        meta["sampling"] = {"temperature": args.temperature}
    if meta:
        cfg = json.loads((dst / "config.json").read_text())
        cfg.update(meta)
        (dst / "config.json").write_text(json.dumps(cfg, indent=1) + "\n")
    from safetensors.numpy import load_file

    n_params = sum(v.size for v in load_file(str(dst / "model.safetensors")).values())
    train = config.get("train", {})
    card = {
        "description": args.description,
        "family": config.get("model"),
        "training_data": _describe_data(config.get("data") or {}),
        "parameters": int(n_params),
        "training_time": args.training_time,
        "steps": config.get("step", train.get("steps")),  # the embedded checkpoint's step
        "training_steps": train.get("steps"),
        "curriculum": train.get("curriculum"),
    }
    if config.get("model") != "revolution":  # the auto-condition curriculum is Dance Revolution's
        card.pop("curriculum")
    if args.report:
        report = json.loads(Path(args.report).read_text())
        card["metrics_source"] = "dancekit evaluate on the tang2018 test split (6 dances), see docs/BENCHMARKS.md"
        card["metrics"] = _pick(report)
    components: dict = {}
    if args.genre_model:
        card["genre_models"] = _embed_genre_models(dst, args.genre_model)
        card["genre_training"] = args.genre_training
    if args.genre_report:
        steer = json.loads(Path(args.genre_report).read_text())
        card["genre_steering"] = {k: steer[k] for k in ("split", "read_back", "n") if k in steer}
    if args.music_attributes:
        _copy_checkpoint(Path(args.music_attributes), dst / "music_attributes")
        card["music_attributes"] = args.music_attributes_training
        components["genre_reader"] = "music_attributes"
    if args.foot_constraint:
        _copy_checkpoint(Path(args.foot_constraint), dst / "foot_constraint", weights=False)
        _half_weights(Path(args.foot_constraint), dst / "foot_constraint")
        components["foot_constraint"] = "foot_constraint"
    if args.genre_model:
        components["genres"] = {g: f"genres/{g}" for g in card["genre_models"]}
    if components:
        declare_components(dst, components)
    if args.report_none:
        card["metrics_genre_none"] = _pick(json.loads(Path(args.report_none).read_text()))
    if args.scores:
        scores = json.loads(Path(args.scores).read_text())
        card["scores"] = scores[0] if isinstance(scores, list) and len(scores) == 1 else scores
    if args.float16:
        card["weights"] = "float16 (computed in float32)"
    if args.card:
        card.update(json.loads(Path(args.card).read_text()))
    (dst / "card.json").write_text(json.dumps(card, indent=1) + "\n")
    size = sum(f.stat().st_size for f in dst.rglob("*") if f.is_file())
    print(f"embedded {src} as {dst} ({size / 1e6:.2f} MB)")
    return 0


def _meta_item(item: str) -> tuple[str, object]:
    """``KEY=JSON`` → ``(KEY, value)``."""
    key, sep, value = item.partition("=")
    if not sep:
        raise SystemExit(f"embed_model: --meta expects KEY=JSON, got {item!r}")
    return key, json.loads(value)


def _embed_genre_models(dst: Path, items: list[str]) -> list[str]:
    """Copy each ``GENRE=DIR`` checkpoint to ``dst/genres/GENRE`` with float16 weights."""
    genres = []
    for item in items:
        genre, sep, folder = item.partition("=")
        if not sep or not genre or not folder:
            raise SystemExit(f"embed_model: --genre-model expects GENRE=DIR, got {item!r}")
        src, out = Path(folder), dst / "genres" / genre
        _copy_checkpoint(src, out, weights=False)
        _half_weights(src, out)
        genres.append(genre)
    return genres


def _half_weights(src: Path, out: Path) -> None:
    """``src/model.safetensors`` written to ``out`` with its floating-point tensors as float16."""
    import torch
    from safetensors.torch import load_file, save_file

    state = load_file(str(src / "model.safetensors"))
    save_file({k: v.half() if v.is_floating_point() else v for k, v in state.items()}, str(out / "model.safetensors"))
    assert all(torch.isfinite(v.float()).all() for v in load_file(str(out / "model.safetensors")).values())


def _copy_checkpoint(src: Path, out: Path, *, weights: bool = True) -> None:
    """Copy a checkpoint folder's files (``KEEP``; without the weights if not ``weights``) to ``out``, with the
    paths in its ``config.json`` (the data root, ``--init``) made relative to the repository when they lie in
    it, so that a shipped model does not record the machine it was trained on."""
    out.mkdir(parents=True)
    for name in KEEP:
        if name == "config.json" or (name == "model.safetensors" and not weights):
            continue
        shutil.copy2(src / name, out / name)
    config = json.loads((src / "config.json").read_text())
    config.pop("components", None)  # the parts embedded with it are declared afresh (declare_components)
    if isinstance(config.get("data"), dict) and config["data"].get("root"):
        config["data"]["root"] = _portable(config["data"]["root"])
    if config.get("init"):
        config["init"] = _portable(config["init"])
    (out / "config.json").write_text(json.dumps(config, indent=1) + "\n")


def _portable(path: str) -> str:
    p = Path(path)
    return p.relative_to(ROOT).as_posix() if p.is_absolute() and p.is_relative_to(ROOT) else path


def _describe_data(data: dict) -> str:
    """'tang2018 training split: 26 dances (19 waltz, ...)' from a checkpoint's data entry."""
    codes = {"W": "waltz", "R": "rumba", "C": "cha-cha", "T": "tango"}
    names = data.get("train", [])
    counts: dict[str, int] = {}
    for n in names:
        g = codes.get(n.split("_")[1], "?") if n.count("_") >= 2 else "?"
        counts[g] = counts.get(g, 0) + 1
    parts = ", ".join(f"{v} {k}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
    return f"tang2018 training split (whole dances, genre-stratified, seed 0): {len(names)} dances ({parts})"


def _pick(report: dict) -> dict:
    """The headline test-split metrics of a ``dancekit evaluate`` report."""
    metrics = report["metrics"]
    return {k: round(float(metrics[k]), 4) for k in CARD_METRICS if metrics.get(k) is not None}


if __name__ == "__main__":
    sys.exit(main())
