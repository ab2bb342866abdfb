import subprocess
import sys

from dancekit.cli.main import main


def test_help_lists_verbs(capsys):
    try:
        main(["--help"])
    except SystemExit as exc:
        assert exc.code == 0
    out = capsys.readouterr().out
    assert "VERB" in out


def test_no_verb_is_an_error():
    assert main([]) == 2


def test_console_script_runs():
    r = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "--version"], capture_output=True, text=True)
    assert r.returncode == 0 and "dancekit" in r.stdout
