"""The layer order and the private-name rule of docs/ARCHITECTURE.md, checked on the AST of ``src/dancekit``.

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
    "serve": {"audio", "features", "motion", "metrics", "models", "checkpoints", "data", "training", "pipelines",
              "live", "render", "export", "evaluation"},
    "cli": {"audio", "features", "motion", "metrics", "models", "checkpoints", "data", "training", "pipelines",
            "live", "render", "export", "evaluation", "serve"},
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


# --- no private names across modules --------------------------------------------------------------------------


def _module_name(path: Path, root: Path) -> str:
    """``dancekit.motion.footlock`` for ``root/motion/footlock.py``; ``dancekit.motion`` for its ``__init__``."""
    parts = ("dancekit", *path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _owner(dotted: str) -> str | None:
    """The scope a dotted dancekit path is private to: the path before its first private part (``dancekit.motion``
    for ``dancekit.motion._filters.gaussian_filter1d``, ``dancekit.motion.footlock`` for
    ``dancekit.motion.footlock._savgol``); None when no part is private."""
    parts = dotted.split(".")
    for i, part in enumerate(parts):
        if _is_private(part):
            return ".".join(parts[:i])
    return None


def private_access(src: Path = SRC) -> list[str]:
    """Every use, inside ``src``, of a dancekit name that is private to another scope.

    The rule: a name whose dotted path has a part starting with ``_`` (dunders such as ``__version__`` aside)
    is private to the module or package that holds that part, its *owner*: ``_savgol`` in
    ``dancekit.motion.footlock`` is private to that module; the module ``dancekit.render._scene`` is private
    to the package ``dancekit.render`` (every module inside ``render/`` may import it); ``dancekit._io`` to
    ``dancekit`` (every module). A module may use a private name only when it is the owner or lies inside it.
    Checked: ``from X import name`` (and ``import X``) of such a path, and attribute access ``alias._name`` /
    ``alias._module.name`` on a name bound by an import, at the top of a file or inside a function.
    """
    bad = []
    for path in sorted(src.rglob("*.py")):
        here = _module_name(path, src)
        tree = ast.parse(path.read_text(), filename=str(path))
        bound: dict[str, str] = {}  # local name -> the dancekit path it was imported as
        uses: list[tuple[int, str]] = []
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] == "dancekit":
                        uses.append((node.lineno, a.name))
                        if a.asname:
                            bound[a.asname] = a.name
                        else:
                            bound[a.name.split(".")[0]] = "dancekit"
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                    and node.module.split(".")[0] == "dancekit":
                for a in node.names:
                    uses.append((node.lineno, f"{node.module}.{a.name}"))
                    bound[a.asname or a.name] = f"{node.module}.{a.name}"
        for node in ast.walk(tree):  # attribute chains on imported names: fl._savgol, dancekit.motion._filters
            if isinstance(node, ast.Attribute):
                chain, base = [], node
                while isinstance(base, ast.Attribute):
                    chain.append(base.attr)
                    base = base.value
                if isinstance(base, ast.Name) and base.id in bound:
                    uses.append((node.lineno, ".".join([bound[base.id], *reversed(chain)])))
        for line, dotted in sorted(set(uses)):
            owner = _owner(dotted)
            if owner is not None and here != owner and not here.startswith(owner + "."):
                bad.append(f"{path.relative_to(src)}:{line}: {here} uses {dotted}, private to {owner}")
    return bad


def test_no_module_uses_another_modules_private_names():
    bad = private_access()
    assert not bad, "\n".join(bad)


def test_the_private_check_catches_planted_uses_and_allows_the_owners(tmp_path):
    root = tmp_path / "dancekit"
    (root / "motion").mkdir(parents=True)
    (root / "render").mkdir()
    (root / "pipelines").mkdir()
    (root / "motion" / "footlock.py").write_text("def _savgol():\n    pass\n\n\ndef f():\n    return _savgol()\n")
    (root / "motion" / "_filters.py").write_text("def g():\n    pass\n")
    (root / "motion" / "cleanup.py").write_text("from dancekit.motion._filters import g\nfrom dancekit._io import a\n")
    (root / "render" / "_scene.py").write_text("from dancekit.motion._filters import g\n")  # another package's
    (root / "render" / "mp4.py").write_text("from dancekit.render._scene import s\n")  # its own package's: fine
    (root / "pipelines" / "stages.py").write_text(
        "from dancekit.motion import footlock as fl\nfrom dancekit.motion.footlock import _savgol\n\n\n"
        "def h():\n    return fl._savgol, fl.f, fl.__name__\n")
    bad = private_access(root)
    assert len(bad) == 3, bad
    assert sum("render/_scene.py:1:" in b and b.endswith("private to dancekit.motion") for b in bad) == 1, bad
    assert sum("pipelines/stages.py" in b and "footlock._savgol" in b for b in bad) == 2, bad  # import, fl._savgol
