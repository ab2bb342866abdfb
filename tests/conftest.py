"""Shared fixtures: a seeded rng, paths to ../shared (tests needing it skip when absent)."""

from __future__ import annotations

import faulthandler
import os
import sys
from pathlib import Path

# One thread per process for torch and the BLAS (set before either is imported; child processes inherit it): the
# tests' models and arrays are small, so a second thread costs more in synchronisation and idle spinning than it
# saves (as for `dancekit dance --threads`, whose default is 1), and every test sees the same thread count (an
# in-process `dancekit dance` sets torch's to 1 for the rest of the session, whichever test runs it first).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

# `make test` runs one test process per core (pytest-xdist). librosa's numba functions cache their compiled code on
# disk, and numba's cache is not safe for processes that fill it at the same time (numba/numba#4807, #10128: a
# worker segfaulted in librosa's peak_pick on a fresh clone). Each worker (and the processes it starts) gets its
# own cache folder, kept between runs; set before anything imports numba.
if os.environ.get("PYTEST_XDIST_WORKER") and "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = str(Path(__file__).resolve().parents[1] / ".pytest_cache" / "numba"
                                        / os.environ["PYTEST_XDIST_WORKER"])

import numpy as np  # noqa: E402
import pytest  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
# the tests live in one folder per layer (tests/motion/, tests/pipelines/, ...); their shared helpers
# (_media.py, _signals.py, _prepared.py, _style.py) stay here, importable from every folder
sys.path.insert(0, str(Path(__file__).resolve().parent))
SHARED = ROOT.parent / "shared"
TANG2018 = SHARED / "data" / "tang2018"
MUSIC = SHARED / "music"
FIXTURES = SHARED / "fixtures"

# the three real songs (the other two recordings are non-music, for robustness tests)
SONGS = [
    MUSIC / "Kevin_MacLeod_-_P_I_Tchaikovsky_Dance_of_the_Sugar_Plum_Fairy.ogg",
    MUSIC / "Kevin_MacLeod_-_Vibe_Ace.ogg",
    MUSIC / "brahms_hungarian_dance_5.ogg",
]
NON_MUSIC = [
    MUSIC / "456440__inspectorj__bird-whistling-robin-single-13.ogg",
    MUSIC / "glacier-bay-humpback.ogg",
]


# The last bound on a test: a test still running after this many seconds (pytest-timeout's 600 s did not end it:
# a thread that holds the GIL in native code, e.g. a deadlock in a library's destructor, stops pytest-timeout's
# signal and its timer thread alike) has every thread's stack written to stderr and ends the test process with
# exit code 1 — CI fails at once instead of hanging until its own limit. faulthandler's watchdog is a native thread.
HANG_S = float(os.environ.get("DANCEKIT_TEST_HANG_S", "900"))
_HANG_FD: int | None = None


def pytest_configure(config):
    global _HANG_FD
    _HANG_FD = os.dup(sys.stderr.fileno())  # the terminal's stderr (pytest's capture is not running here)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if _HANG_FD is not None:
        faulthandler.dump_traceback_later(HANG_S, exit=True, file=_HANG_FD)
    try:
        return (yield)
    finally:
        faulthandler.cancel_dump_traceback_later()


def _need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"{path} not available (../shared is not beside the repository)")
    return path


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)


@pytest.fixture
def shared_dir() -> Path:
    return _need(SHARED)


@pytest.fixture
def tang2018_dir() -> Path:
    return _need(TANG2018)


@pytest.fixture
def music_dir() -> Path:
    return _need(MUSIC)


@pytest.fixture
def fixtures_dir() -> Path:
    return _need(FIXTURES)


@pytest.fixture(scope="session", autouse=True)
def _isolated_feature_cache(tmp_path_factory):
    """Tests never read or write the user's feature cache."""
    import os

    old = os.environ.get("DANCEKIT_CACHE")
    os.environ["DANCEKIT_CACHE"] = str(tmp_path_factory.mktemp("feature_cache"))
    yield
    if old is None:
        os.environ.pop("DANCEKIT_CACHE", None)
    else:
        os.environ["DANCEKIT_CACHE"] = old


@pytest.fixture(scope="session")
def prepared_tang2018(tmp_path_factory):
    """All 37 tang2018 dances prepared once per session (music2dance features only, to stay fast)."""
    if not TANG2018.exists():
        pytest.skip(f"{TANG2018} not available")
    from dancekit.data import PreparedData, prepare_tang2018

    out = tmp_path_factory.mktemp("prepared") / "tang2018"
    prepare_tang2018(TANG2018, out, presets=("music2dance",), progress=False)
    return PreparedData(out)
