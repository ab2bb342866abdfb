"""Copy a dual run's ``RUN/model`` (or ``RUN/best`` with ``--best``) to ``RUN/ev`` with the embedded ``dual``
model's sampling and stage settings (``smooth_frames``, ``beat_min_gap``, ``beat_threshold``: chosen on the
validation split, docs/DUAL.md; with ``--stages`` also its ``foot_lock`` entry, chosen on validation in
issue 15), so that an ablation run is scored with the same settings as the shipped model (Table 4,
docs/DUAL.md).

    python scripts/dual_copy_settings.py runs/ab/NAME                  # model/ -> ev/ (the 100-step table)
    python scripts/dual_copy_settings.py runs/t4/NAME --best --stages  # best/ -> ev/ (the 380-step table)
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

SAMPLING_KEYS = ("smooth_frames", "beat_min_gap", "beat_threshold")
STAGE_KEYS = ("foot_lock",)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a `dancekit train dual` run folder")
    ap.add_argument("--best", action="store_true", help="copy RUN/best (lowest validation loss), not RUN/model")
    ap.add_argument("--stages", action="store_true", help="also copy the shipped model's stage entries (foot_lock)")
    args = ap.parse_args(argv)
    ev = args.run / "ev"
    if ev.exists():
        shutil.rmtree(ev)
    shutil.copytree(args.run / ("best" if args.best else "model"), ev)
    cfg = json.loads((ev / "config.json").read_text())
    shipped = json.loads((Path(__file__).parents[1] / "src/dancekit/assets/models/dual/config.json").read_text())
    keys = SAMPLING_KEYS + (STAGE_KEYS if args.stages else ())
    for key in keys:
        if key in shipped:
            cfg[key] = shipped[key]
    (ev / "config.json").write_text(json.dumps(cfg, indent=1))
    print(ev, "step", cfg.get("step"), {k: cfg[k] for k in keys if k in cfg})
    return 0


if __name__ == "__main__":
    sys.exit(main())
