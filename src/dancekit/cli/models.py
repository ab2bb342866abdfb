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
    from dancekit.checkpoints import model_cards

    cards = model_cards()
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
