"""The layer order of docs/ARCHITECTURE.md, checked on the import graph of ``src/dancekit``.

Every ``import dancekit.X`` / ``from dancekit.X import ...`` of every module — at the top or inside a
function, since a lazy import is still a dependency — must name a package its layer may use. The table
below is the one in docs/ARCHITECTURE.md (a test there keeps the two equal).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "dancekit"
DOC = Path(__file__).resolve().parents[1] / "docs" / "ARCHITECTURE.md"

BASE = {"errors", "_io", "_checks", "registry", "__init__"}  # every layer may use these
# package → the dancekit packages it may import (besides BASE and itself)
ALLOWED: dict[str, set[str]] = {
    "errors": set(),
    "_io": set(),
    "_checks": set(),
    "registry": set(),
    "audio": set(),
    "features": {"audio"},
    "motion": set(),
    "metrics": {"motion"},
    "models": {"motion"},
    "checkpoints": {"models"},
    "data": {"audio", "features", "motion", "checkpoints"},
    "training": {"data", "models", "motion", "checkpoints", "features", "audio"},
    "pipelines": {"audio", "features", "motion", "models", "checkpoints"},
    "live": {"audio", "features", "motion", "models", "checkpoints", "pipelines"},
    "render": {"motion", "audio"},
    "export": {"motion", "render", "audio"},
    "evaluation": {"audio", "features", "motion", "metrics", "models", "checkpoints", "data", "pipelines",
                   "render", "export", "training"},
    "cli": {"audio", "features", "motion", "metrics", "models", "checkpoints", "data", "training", "pipelines",
            "live", "render", "export", "evaluation"},
    "__init__": set(),  # the package root re-exports the errors only
}


def _package_of(path: Path, root: Path) -> str:
    """The top-level package (or module) of ``path`` under ``root``: ``metrics``, ``registry``, ``__init__``."""
    head = path.relative_to(root).parts[0]
    return head[:-3] if head.endswith(".py") else head


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, first package name after ``dancekit.``) of every dancekit import in a module."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] if node.module != "dancekit" else [f"dancekit.{a.name}" for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            pytest.fail(f"{path}:{node.lineno}: relative import (the project uses absolute imports)")
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "dancekit" and len(parts) > 1:
                # `from dancekit import __version__`: a name of the package root, not a layer
                is_layer = (SRC / parts[1]).is_dir() or (SRC / f"{parts[1]}.py").is_file()
                out.append((node.lineno, parts[1] if is_layer else "__init__"))
    return out


def violations(src: Path = SRC) -> list[str]:
    bad = []
    for path in sorted(src.rglob("*.py")):
        pkg = _package_of(path, src)
        if pkg not in ALLOWED:
            bad.append(f"{path}: package {pkg!r} has no place in the layer table (add it to docs/ARCHITECTURE.md)")
            continue
        for line, target in _imports(path):
            if target == pkg or target in BASE or target in ALLOWED[pkg]:
                continue
            bad.append(f"{path.relative_to(src)}:{line}: {pkg} imports dancekit.{target}, against the layer order")
    return bad


def test_no_module_imports_against_the_layer_order():
    bad = violations()
    assert not bad, "\n".join(bad)


def test_the_check_catches_a_planted_upward_import(tmp_path):
    """The checker itself fails on an import against the flow (metrics importing training, lazily)."""
    root = tmp_path / "dancekit"
    (root / "metrics").mkdir(parents=True)
    (root / "metrics" / "x.py").write_text("def f():\n    from dancekit.training import train\n    return train\n")
    (root / "motion").mkdir()
    (root / "motion" / "y.py").write_text("from dancekit.errors import ParameterError\nimport dancekit.motion.z\n")
    bad = violations(root)
    assert len(bad) == 1 and "metrics imports dancekit.training" in bad[0]


def test_architecture_doc_states_the_same_table():
    """docs/ARCHITECTURE.md lists, for every package, exactly the packages this test allows."""
    text = DOC.read_text()
    rows = dict(re.findall(r"^\| `(\w+)` \| ([^|]*) \|", text, flags=re.M))
    for pkg, allowed in ALLOWED.items():
        if pkg in BASE or pkg == "__init__":
            continue
        assert pkg in rows, f"docs/ARCHITECTURE.md has no row for `{pkg}`"
        doc = {w.strip("` ") for w in rows[pkg].split(",") if w.strip() and w.strip() != "—"}
        assert doc == allowed, f"`{pkg}`: the doc allows {sorted(doc)}, the test {sorted(allowed)}"


def test_every_package_is_in_the_table():
    packages = {_package_of(p, SRC) for p in SRC.iterdir() if (p.is_dir() and (p / "__init__.py").exists())
                or (p.suffix == ".py")}
    assert packages <= set(ALLOWED), sorted(packages - set(ALLOWED))
