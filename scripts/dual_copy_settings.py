"""Copy a dual run's ``RUN/model`` to ``RUN/ev`` with the embedded ``dual`` model's sampling settings
(``smooth_frames``, ``beat_min_gap``, ``beat_threshold``: chosen on the validation split, docs/DUAL.md), so that
an ablation run is scored with the same settings as the shipped model (Table 4, docs/DUAL.md).

    python scripts/dual_copy_settings.py runs/ab/NAME
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    run = Path((argv or sys.argv[1:])[0])
    ev = run / "ev"
    if ev.exists():
        shutil.rmtree(ev)
    shutil.copytree(run / "model", ev)
    cfg = json.loads((ev / "config.json").read_text())
    shipped = json.loads((Path(__file__).parents[1] / "src/dancekit/assets/models/dual/config.json").read_text())
    for key in ("smooth_frames", "beat_min_gap", "beat_threshold"):
        cfg[key] = shipped[key]
    (ev / "config.json").write_text(json.dumps(cfg, indent=1))
    print(ev, {k: cfg[k] for k in ("smooth_frames", "beat_min_gap", "beat_threshold")})
    return 0


if __name__ == "__main__":
    sys.exit(main())
