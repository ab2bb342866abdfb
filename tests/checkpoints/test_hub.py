"""Hub models (``hf:USER/NAME[@REV]``) and ``dancekit models push``, tested without internet.

A small HTTP server on 127.0.0.1 serves model repositories in the Hugging Face Hub's layout, with only
the endpoints that huggingface_hub's ``snapshot_download`` and ``create_repo`` / ``create_commit`` call:

- ``GET /api/models/U/N[/revision/REV]``: the repository's info at a revision (``sha``: the commit);
- ``GET /api/models/U/N/tree/REV?recursive=..``: the files of a commit (path, size, git blob id);
- ``HEAD`` / ``GET /U/N/resolve/REV/PATH``: a file, with ``ETag`` and ``X-Repo-Commit``;
- ``POST /api/repos/create``, ``POST /api/validate-yaml``, ``POST /api/models/U/N/preupload/REV`` (every
  file ``regular``) and ``POST /api/models/U/N/commit/REV`` (the ndjson commit);
- ``GET /api/agent-harnesses`` (an empty registry): huggingface_hub's user-agent header asks for it once.

The server answers anything else with 500, so a test fails if huggingface_hub asks for more. Commits are
sha1s of their content, so a revision pinned to the first commit keeps reading the first upload.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import shutil
import socket
import subprocess
import sys
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest

from dancekit.checkpoints import hf as hfmod
from dancekit.checkpoints import resolve_model
from dancekit.checkpoints.hub import MODELS_DIR
from dancekit.errors import CheckpointError, ParameterError

ROOT = Path(__file__).resolve().parents[2]
M2D = MODELS_DIR / "music2dance"  # a composite model: genre_reader and foot_constraint component folders


class Hub:
    """In-memory repositories: ``repos[repo_id] = {"refs": {branch: sha}, "commits": {sha: {path: bytes}}}``."""

    def __init__(self):
        self.repos: dict[str, dict] = {}
        self.log: list[tuple[str, str]] = []  # (method, path) of every request
        self.unknown: list[tuple[str, str]] = []
        self.read_only = False  # True: writes answer 401 (no token, or a read-only one)

    def add(self, repo: str, files: dict[str, bytes], branch: str = "main") -> str:
        r = self.repos.setdefault(repo, {"refs": {}, "commits": {}})
        parent = r["commits"].get(r["refs"].get(branch) or r["refs"].get("main"), {})  # a new branch: from main
        tree = {**parent, **files}
        sha = hashlib.sha1(json.dumps({k: hashlib.sha1(v).hexdigest() for k, v in sorted(tree.items())})
                           .encode() + repo.encode() + str(len(r["commits"])).encode()).hexdigest()
        r["commits"][sha] = tree
        r["refs"][branch] = sha
        return sha

    def commit_of(self, repo: str, rev: str) -> str | None:
        r = self.repos[repo]
        return r["refs"].get(rev) or (rev if rev in r["commits"] else None)


def _blob_id(data: bytes) -> str:
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def _handler(hub: Hub):
    class H(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, *args):  # quiet
            pass

        def _send(self, code: int, body: bytes = b"", headers: dict | None = None, ctype="application/json"):
            self.send_response(code)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(body)))
            for k, v in (headers or {}).items():
                self.send_header(k, v)
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(body)

        def _json(self, obj, code=200, headers=None):
            self._send(code, json.dumps(obj).encode(), headers)

        def _error(self, code, error_code, message):
            self._json({"error": message}, code, {"X-Error-Code": error_code, "X-Error-Message": message})

        def _body(self) -> bytes:
            return self.rfile.read(int(self.headers.get("Content-Length") or 0))

        def _repo(self, parts):
            repo = f"{parts[0]}/{parts[1]}"
            if repo not in hub.repos:
                self._error(404, "RepoNotFound", f"Repository not found: {repo}")
                return None
            return repo

        def _route(self):
            url = urlsplit(self.path)
            parts = [unquote(p) for p in url.path.strip("/").split("/")]
            hub.log.append((self.command, url.path))
            m = self.command
            if m == "GET" and parts[:2] == ["api", "models"] and len(parts) == 4:  # the info at the default branch
                parts += ["revision", "main"]
            if m == "GET" and parts[:2] == ["api", "models"] and len(parts) >= 6 and parts[4] in ("revision", "tree"):
                repo = self._repo(parts[2:4])
                if repo is None:
                    return
                sha = hub.commit_of(repo, "/".join(parts[5:]) if parts[4] == "revision" else parts[5])
                if sha is None:
                    return self._error(404, "RevisionNotFound", f"Invalid rev id: {parts[5]}")
                files = hub.repos[repo]["commits"][sha]
                if parts[4] == "revision":
                    return self._json({"id": repo, "modelId": repo, "sha": sha, "private": False,
                                       "siblings": [{"rfilename": p} for p in sorted(files)]})
                dirs = sorted({"/".join(p.split("/")[:i]) for p in files for i in range(1, p.count("/") + 1)})
                return self._json([{"type": "directory", "path": d, "oid": "0" * 40, "size": 0} for d in dirs]
                                  + [{"type": "file", "path": p, "size": len(b), "oid": _blob_id(b)}
                                     for p, b in sorted(files.items())])
            if m in ("GET", "HEAD") and len(parts) >= 5 and parts[2] == "resolve":
                repo = self._repo(parts[:2])
                if repo is None:
                    return
                sha = hub.commit_of(repo, parts[3])
                if sha is None:
                    return self._error(404, "RevisionNotFound", f"Invalid rev id: {parts[3]}")
                path = "/".join(parts[4:])
                data = hub.repos[repo]["commits"][sha].get(path)
                if data is None:
                    return self._error(404, "EntryNotFound", f"{path} not found") or None
                return self._send(200, data, {"ETag": f'"{_blob_id(data)}"', "X-Repo-Commit": sha},
                                  "application/octet-stream")
            if m == "POST" and hub.read_only and "preupload" not in url.path:
                self._body()
                return self._error(401, "Unauthorized", "Invalid credentials in Authorization header")
            if m == "POST" and url.path == "/api/repos/create":
                doc = json.loads(self._body())
                repo = f"{doc['organization']}/{doc['name']}"
                if repo in hub.repos:
                    return self._error(409, "RepoExists", "You already created this model repo")
                hub.repos[repo] = {"refs": {}, "commits": {}}
                return self._json({"url": f"http://{self.headers['Host']}/{repo}", "name": repo})
            if m == "GET" and url.path == "/api/agent-harnesses":  # the user-agent's best-effort registry
                return self._json({"standardEnvVars": [], "harnesses": {}})
            if m == "POST" and url.path == "/api/validate-yaml":
                self._body()
                return self._json({"errors": [], "warnings": []})
            if m == "POST" and parts[:2] == ["api", "models"] and len(parts) >= 6 and parts[4] == "preupload":
                doc = json.loads(self._body())
                if self._repo(parts[2:4]) is None:
                    return
                return self._json({"files": [{"path": f["path"], "uploadMode": "regular", "shouldIgnore": False,
                                              "oid": None} for f in doc["files"]]})
            if m == "POST" and parts[:2] == ["api", "models"] and len(parts) >= 6 and parts[4] == "commit":
                lines = [json.loads(x) for x in self._body().splitlines() if x.strip()]
                repo = self._repo(parts[2:4])
                if repo is None:
                    return
                files = {}
                for item in lines:
                    if item["key"] == "file":
                        assert item["value"]["encoding"] == "base64"
                        files[item["value"]["path"]] = base64.b64decode(item["value"]["content"])
                    elif item["key"] != "header":
                        return self._error(400, "Unsupported", f"unsupported commit operation {item['key']}")
                sha = hub.add(repo, files, branch="/".join(parts[5:]))
                return self._json({"commitUrl": f"http://{self.headers['Host']}/{repo}/commit/{sha}",
                                   "commitOid": sha, "pullRequestUrl": None})
            hub.unknown.append((m, self.path))
            self._json({"error": f"not served by the test hub: {m} {self.path}"}, 500)

        do_GET = do_HEAD = do_POST = _route

    return H


@pytest.fixture
def hub_env(tmp_path, monkeypatch):
    """A loopback hub at HF_ENDPOINT, an empty models folder, Hugging Face's config kept out of the way."""
    hub = Hub()
    server = ThreadingHTTPServer(("127.0.0.1", 0), _handler(hub))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    host, port = server.server_address
    hub.url = f"http://{host}:{port}"
    monkeypatch.setenv("HF_ENDPOINT", hub.url)
    monkeypatch.setenv("DANCEKIT_MODELS", str(tmp_path / "models"))
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf_home"))
    monkeypatch.setenv("HF_TOKEN", "hf_loopback_test_token")
    monkeypatch.delenv("HF_HUB_OFFLINE", raising=False)
    hub.server = server
    yield hub
    server.shutdown()
    server.server_close()
    assert not hub.unknown, f"huggingface_hub asked for endpoints the test hub does not serve: {hub.unknown}"


def _closed_port_url() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"http://127.0.0.1:{port}"  # nothing listens there once the socket is closed


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_parse_hub_name():
    assert hfmod.parse_hub_name("hf:alice/dance-1") == ("alice/dance-1", None)
    assert hfmod.parse_hub_name("hf:alice/dance.v2@v1.0") == ("alice/dance.v2", "v1.0")
    assert hfmod.parse_hub_name("hf:a/b@" + "c" * 40) == ("a/b", "c" * 40)
    for bad in ("hf:alice", "hf:alice/", "hf:/b", "hf:a/b/c", "hf:a/b@", "hf:a/../b", "hf:a/b@x..y", "hf:a b/c"):
        with pytest.raises(ParameterError, match="hf:USER/NAME"):
            hfmod.parse_hub_name(bad)


def test_download_checks_and_caches_a_composite_model(hub_env):
    sha = hub_env.add("alice/m2d", _files(M2D))
    folder = resolve_model("hf:alice/m2d")
    cache = Path(hfmod.hub_cache_dir())
    assert folder == cache / "models--alice--m2d" / "snapshots" / sha
    assert _files(folder) == _files(M2D)  # every file, the component folders included
    assert (cache / "models--alice--m2d" / "refs" / "main").read_text() == sha
    # the same name again in this process: no request
    n = len(hub_env.log)
    assert resolve_model("hf:alice/m2d") == folder
    assert len(hub_env.log) == n


def test_revision_pinning(hub_env):
    first = hub_env.add("alice/m2d", _files(M2D))
    card = json.loads((M2D / "card.json").read_text())
    second = hub_env.add("alice/m2d", {"card.json": json.dumps({**card, "description": "retrained"}).encode()})
    assert first != second
    old = resolve_model(f"hf:alice/m2d@{first}")
    new = resolve_model("hf:alice/m2d")
    assert old.name == first and new.name == second
    assert json.loads((old / "card.json").read_text()) == card
    assert json.loads((new / "card.json").read_text())["description"] == "retrained"
    hub_env.add("alice/m2d", {"card.json": b"{}"}, branch="v1")  # a branch name as the revision
    assert json.loads((resolve_model("hf:alice/m2d@v1") / "card.json").read_text()) == {}
    with pytest.raises(CheckpointError, match="no such revision"):
        resolve_model("hf:alice/m2d@nope")


def test_refuses_a_repository_that_is_not_a_dancekit_model(hub_env):
    hub_env.add("bob/llm", {"config.json": json.dumps({"architectures": ["GPT2LMHeadModel"]}).encode(),
                            "pytorch_model.bin": b"\0" * 1000})
    with pytest.raises(CheckpointError, match=r"hf:bob/llm is not a dancekit model: its config.json has no 'model'"):
        resolve_model("hf:bob/llm")
    assert not any("pytorch_model.bin" in path for _, path in hub_env.log)  # refused before the weights
    hub_env.add("bob/empty", {"README.md": b"# nothing"})
    with pytest.raises(CheckpointError, match="hf:bob/empty is not a dancekit model: the repository has no config"):
        resolve_model("hf:bob/empty")
    with pytest.raises(CheckpointError, match="no such model repository"):
        resolve_model("hf:bob/missing")


def test_no_network_is_one_clear_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HF_ENDPOINT", _closed_port_url())
    monkeypatch.setenv("DANCEKIT_MODELS", str(tmp_path / "models"))
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf_home"))
    monkeypatch.delenv("HF_HUB_OFFLINE", raising=False)
    with pytest.raises(CheckpointError, match=r"^cannot download hf:alice/m2d from http://127\.0\.0\.1:\d+ \(") as e:
        resolve_model("hf:alice/m2d")
    assert "\n" not in str(e.value)
    # the CLI (in-process: the same main() the console script runs): one line on stderr, exit 2, nothing else
    from dancekit.cli.main import main

    capsys.readouterr()
    assert main(["dance", str(tmp_path / "song.wav"), "-o", str(tmp_path / "out"), "--model", "hf:alice/m2d"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "audio file not found" in err  # the song is checked first: no download for a bad song
    song = tmp_path / "song.wav"
    _write_wav(song)
    assert main(["dance", str(song), "-o", str(tmp_path / "out"), "--model", "hf:alice/m2d", "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "cannot download hf:alice/m2d" in lines[0], lines
    assert not (tmp_path / "out").exists()


def _write_wav(path: Path, seconds: float = 2.0) -> None:
    import soundfile as sf

    t = np.arange(int(22050 * seconds)) / 22050
    sf.write(path, 0.3 * np.sin(2 * np.pi * 220 * t) * (np.sin(2 * np.pi * 2 * t) > 0), 22050)


def test_offline_mode_reads_a_prefilled_cache(tmp_path, monkeypatch):
    # Hugging Face's cache layout, filled by hand: refs/main -> the commit, snapshots/<commit>/ the files
    models = tmp_path / "models"
    repo = models / "hf" / "models--alice--m2d"
    sha = "0123456789abcdef0123456789abcdef01234567"
    shutil.copytree(M2D, repo / "snapshots" / sha)
    (repo / "refs").mkdir()
    (repo / "refs" / "main").write_text(sha)
    monkeypatch.setenv("DANCEKIT_MODELS", str(models))
    monkeypatch.setenv("HF_ENDPOINT", _closed_port_url())  # any request would fail
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    assert resolve_model("hf:alice/m2d") == repo / "snapshots" / sha
    assert resolve_model(f"hf:alice/m2d@{sha}") == repo / "snapshots" / sha
    with pytest.raises(CheckpointError, match=r"hf:alice/other is not in the hub cache .* HF_HUB_OFFLINE is set"):
        resolve_model("hf:alice/other")


def test_offline_after_a_download_with_the_hub_gone(hub_env, monkeypatch):
    sha = hub_env.add("alice/m2d", _files(M2D))
    folder = resolve_model("hf:alice/m2d")
    hub_env.server.shutdown()
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    n = len(hub_env.log)
    assert resolve_model("hf:alice/m2d") == folder and folder.name == sha
    assert len(hub_env.log) == n


def test_push_then_dance_from_the_hub(hub_env, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    p = subprocess.run([sys.executable, "-m", "dancekit.cli.main", "models", "push", str(M2D), "carol/m2d"],
                       env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stderr == ""
    sha = hub_env.repos["carol/m2d"]["refs"]["main"]
    assert sha in p.stdout and "hf:carol/m2d" in p.stdout
    uploaded = hub_env.repos["carol/m2d"]["commits"][sha]
    readme = uploaded.pop("README.md").decode()
    assert uploaded == _files(M2D)
    assert readme.startswith("---\nlibrary_name: dancekit\n") and "--model hf:carol/m2d" in readme
    assert "music2dance" in readme

    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline("hf:carol/m2d")
    ref = load_pipeline(str(M2D))
    song = tmp_path / "song.wav"
    _write_wav(song, 3.0)
    a = pipe.dances(str(song), seeds=[3], progress=False)[0].motion
    b = ref.dances(str(song), seeds=[3], progress=False)[0].motion
    np.testing.assert_array_equal(np.asarray(a.positions), np.asarray(b.positions))


def test_push_refuses_a_folder_that_is_not_a_checkpoint(hub_env, tmp_path):
    from dancekit.cli.main import main

    (tmp_path / "nope").mkdir()
    with pytest.raises(CheckpointError, match="config.json"):
        hfmod.push_model(tmp_path / "nope", "carol/x")
    part = tmp_path / "part"
    shutil.copytree(M2D, part)
    shutil.rmtree(part / "foot_constraint")
    with pytest.raises(CheckpointError, match="foot_constraint"):
        hfmod.push_model(part, "carol/x")
    assert main(["models", "push", str(tmp_path / "nope"), "carol/x"]) == 2
    with pytest.raises(ParameterError, match="not a revision"):
        hfmod.push_model(M2D, "carol/x@v1")
    assert hub_env.log == []  # refused before any request


def test_push_without_write_access_is_one_line(hub_env):
    from dancekit.cli.main import main

    hub_env.read_only = True
    with pytest.raises(CheckpointError, match=r"^cannot push to carol/m2d on http://127\.0\.0\.1:\d+: not allowed "
                                              r"\(HTTP 401\); log in with `hf auth login` or set HF_TOKEN") as e:
        hfmod.push_model(M2D, "carol/m2d")
    assert "\n" not in str(e.value)
    assert main(["models", "push", str(M2D), "carol/m2d"]) == 2
    assert "carol/m2d" not in hub_env.repos
