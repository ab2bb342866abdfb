"""``dancekit models``: list the embedded models with their training data and metrics."""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("models", help="list the models found by name: the user's models folder and the embedded "
                       "models (family, training data, size, metrics)")
    p.add_argument("--json", action="store_true", help="print the model cards as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dancekit import registry
    from dancekit.checkpoints import DEFAULT_MODEL, available_models, components, model_card
    from dancekit.checkpoints.hub import read_meta

    cards = {}
    for name, folder in available_models().items():
        meta = read_meta(folder)
        family = meta["model"]
        kind = registry.get(family).kind if family in registry.families() else "unknown"
        parts = components(folder, meta)
        size = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())
        card = {"name": name, "family": family, "kind": kind, "folder": str(folder), "default": name == DEFAULT_MODEL,
                "size_mb": round(size / 1e6, 2), "genre_models": list(parts.get("genres", {})),
                "reads_genre_from_music": "genre_reader" in parts,
                "genre_condition": list(meta.get("genres", [])) if meta.get("config", {}).get("n_genres") else [],
                **model_card(folder)}
        if not card.get("description"):  # a model without a card.json still says what it is
            genres = meta.get("genres") or meta.get("config", {}).get("genres") or []
            card["description"] = f"a {family} model ({kind}, no model card)" + (
                f"; genres: {', '.join(genres)}" if genres else "")
        cards[name] = card
    if args.json:
        print(json.dumps(cards, indent=1))
        return 0
    if not cards:
        print("no embedded models")
        return 0
    for name, card in cards.items():
        flag = " (default)" if card["default"] else ""
        print(f"{name}{flag}: {card.get('description', '')}")
        print(f"  family: {card['family']} ({card['kind']}); folder: {card['folder']}")
        print(f"  size: {card['size_mb']} MB")
        auto = "auto (read from the music), none" if card["reads_genre_from_music"] else "auto"
        if card["genre_models"]:
            print(f"  --genre: {auto}, {', '.join(card['genre_models'])} (genre models)")
        elif card["genre_condition"]:
            print(f"  --genre: {auto}, {', '.join(card['genre_condition'])} (the model's dance-type condition)")
        for key in ("training_data", "training_time", "parameters"):
            if key in card:
                print(f"  {key.replace('_', ' ')}: {card[key]}")
        for key, value in card.get("metrics", {}).items():
            print(f"  {key}: {value}")
    return 0
