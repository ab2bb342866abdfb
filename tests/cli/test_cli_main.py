import re
import subprocess
import sys

import pytest

from dancekit.cli.main import main

# every verb `dancekit --help` must offer (spelled out here, not read from dancekit.cli.main.VERBS,
# so a verb whose module fails to import and is silently left out of the parser is caught)
EXPECTED_VERBS = ("features", "info", "prepare", "train", "evaluate", "baselines", "compare", "select-checkpoint",
                  "steering", "score-classifier", "dance", "render", "models", "convert", "compose", "serve", "live")


def test_help_lists_verbs(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: dancekit") and "VERB" in out
    listed = re.findall(r"^ {4}([\w-]+)(?: {2,}\S|$)", out, flags=re.MULTILINE)  # "    verb    its help"
    assert listed == list(EXPECTED_VERBS), listed


def test_no_verb_is_an_error():
    assert main([]) == 2


def test_console_script_runs():
    r = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "--version"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "dancekit" in r.stdout
