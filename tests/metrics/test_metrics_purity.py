"""dancekit.metrics is pure: NumPy in, NumPy out, importing only motion helpers, errors and _checks."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

METRICS = Path(__file__).resolve().parents[2] / "src" / "dancekit" / "metrics"
ALLOWED = ("dancekit.metrics", "dancekit.motion", "dancekit.errors", "dancekit._checks")
# no models, files or progress bars; librosa's signal functions (onset detection, resampling: arrays in,
# arrays out, as the music beat scores of issue 20 require) are allowed, its file reading is not
FORBIDDEN_THIRD_PARTY = ("torch", "safetensors", "soundfile", "audioread", "tqdm")
FORBIDDEN_CALLS = ("librosa.load(", "librosa.stream(")


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every module a file imports (at any depth, TYPE_CHECKING blocks included), with its line."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: inside dancekit.metrics
                out.append((node.lineno, "dancekit.metrics." + (node.module or "")))
            else:
                out.append((node.lineno, node.module or ""))
    return out


@pytest.mark.parametrize("path", sorted(METRICS.glob("*.py")), ids=lambda p: p.name)
def test_metrics_module_imports_only_allowed_layers(path):
    bad = []
    for line, name in _imports(path):
        top = name.split(".")[0]
        if top == "dancekit" and not any(name == a or name.startswith(a + ".") for a in ALLOWED):
            bad.append(f"{path.name}:{line} imports {name}")
        if top in FORBIDDEN_THIRD_PARTY:
            bad.append(f"{path.name}:{line} imports {name}")
    bad += [f"{path.name} calls {call}" for call in FORBIDDEN_CALLS if call in path.read_text()]
    assert not bad, "dancekit.metrics must stay pure:\n" + "\n".join(bad)


def test_importing_metrics_loads_no_model_data_or_io_layer():
    code = ("import sys, dancekit.metrics; "
            "print(' '.join(sorted(m for m in sys.modules if m == 'torch' or m.startswith('dancekit.'))))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(METRICS.parents[1]), os.environ.get("PYTHONPATH", "")])}
    loaded = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True,
                            env=env, timeout=120).stdout.split()
    assert "torch" not in loaded
    assert all(m.split(".")[1] in ("metrics", "motion", "errors", "_checks") for m in loaded), loaded
