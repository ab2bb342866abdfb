"""``dancekit models``: list the models found by name with their training data and metrics;
``dancekit models push FOLDER USER/NAME``: upload a checkpoint folder to the Hugging Face Hub."""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("models", help="list the models found by name: the user's models folder and the embedded "
                       "models (family, training data, size, metrics)")
    p.add_argument("--json", action="store_true", help="print the model cards as JSON")
    p.set_defaults(func=run)
    sub2 = p.add_subparsers(dest="action", metavar="{push}")
    push = sub2.add_parser("push", help="upload a checkpoint folder (with its component folders and card) to a "
                           "Hugging Face Hub model repository; others dance with it as --model hf:USER/NAME",
                           description="Upload FOLDER (a checkpoint folder: config.json, model.safetensors, "
                           "stats.npz, card.json and any component folders) to the model repository USER/NAME "
                           "on the Hugging Face Hub ($HF_ENDPOINT), created if missing, with a README.md model "
                           "card made from card.json when the folder has none. Log in first (`hf auth login`) "
                           "or set HF_TOKEN.")
    push.add_argument("folder", help="the checkpoint folder (e.g. RUN/best from `dancekit train`)")
    push.add_argument("repo", metavar="USER/NAME", help="the hub repository")
    push.add_argument("--private", action="store_true", help="create the repository as private")
    push.add_argument("--message", default=None, help="the commit message")
    push.set_defaults(func=run_push)


def run_push(args: argparse.Namespace) -> int:
    from dancekit.checkpoints.hf import endpoint, push_model

    repo = args.repo[3:] if args.repo.startswith("hf:") else args.repo
    commit = push_model(args.folder, repo, private=args.private, message=args.message)
    print(f"pushed {args.folder} to {endpoint()}/{repo} (commit {commit}); dance with it: "
          f"dancekit dance SONG -o OUT --model hf:{repo}")
    return 0


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
        if card.get("live_model"):
            print("  live: its own live model (trained on the features `dancekit live` computes)")
        for key in ("training_data", "training_time", "parameters"):
            if key in card:
                print(f"  {key.replace('_', ' ')}: {card[key]}")
        for key, value in card.get("metrics", {}).items():
            print(f"  {key}: {value}")
    return 0
