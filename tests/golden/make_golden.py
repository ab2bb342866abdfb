"""Writes the golden data that tests/test_golden.py compares against; a maintainer reruns it only for an
intended change of a model, a pipeline stage or a file writer:

    python tests/golden/make_golden.py            # every golden file
    python tests/golden/make_golden.py finished   # only the finished dances (finished_*.npz)

Every golden dance is danced to the same synthetic song: the first 8 s (the finished dances: 5 s) of :func:`dancekit.audio.synth.ode_to_joy`
at 112 BPM and 22050 Hz (a clear beat, so the beat-synchronous warp runs; 201 / 126 frames at 25 fps).

Files (all ``.npz``, float32 numbers, strings as unicode arrays; no pickles):

- ``default_model.npz``: the embedded default (``revolution``) with the stages off and the paper's decoding
  (``variety=False``): ``(T, J, 3)`` positions in cm per case of :data:`MODEL_CASES`.
- ``default_model_variety.npz``: the same with the checkpoint's seed variety on (:data:`VARIETY_CASES`).
- ``music2dance.npz``: the embedded music2dance model, stages off (:data:`M2D_CASES`).
- ``finished_<model>.npz``: what a user gets from each embedded dance model with every default stage on
  (:data:`FINISHED`): the ``DanceResult.notes`` and the files ``export_motion`` writes from it, read back
  as a user's tool would (:func:`user_files`): the npz's arrays (``npz/<key>``), the BVH's hierarchy text
  (``bvh/hierarchy``, everything before ``MOTION``) and its channel values (``bvh/values``, ``(T, C)``:
  root position in cm then Euler angles in degrees, file order), the glb's node names (``glb/nodes``) and
  its accessors (``glb/times`` (T,) s; ``glb/rotation/<node>`` (T, 4) xyzw; ``glb/translation/<node>``
  (T, 3) m; ``glb/inverse_bind`` (N, 16)).

``style_classifier.npz`` is written by tests/models/test_style_model.py (``DANCEKIT_WRITE_GOLDEN=1``).

The tolerances of tests/test_golden.py were measured against another CPU's kernels: on an AVX-512 machine,
``NPY_DISABLE_CPU_FEATURES=X86_V4 OPENBLAS_CORETYPE=Haswell ATEN_CPU_CAPABILITY=avx2 MKL_ENABLE_INSTRUCTIONS=AVX2
ONEDNN_MAX_CPU_ISA=AVX2 python -m pytest tests/test_golden.py`` runs NumPy, OpenBLAS and torch on their AVX2 code
paths (what an AVX2 machine runs); rerun it after regenerating on a new machine.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SR = 22050
SONG_S = 8.0
#: the finished dances' excerpt: the song's first 5 s (126 frames; the golden files stay small)
FINISHED_S = 5.0
BPM = 112.0

#: the raw model pins: (genre, seed) per case
MODEL_CASES = {"none_seed3": ("none", 3), "auto_seed0": ("auto", 0), "rumba_seed1": ("rumba", 1)}
VARIETY_CASES = {"auto_seed0": ("auto", 0), "none_seed3": ("none", 3)}
M2D_CASES = {"waltz_seed0": ("waltz", 0), "auto_seed2": ("auto", 2)}
#: the finished dances: embedded model -> seed (its default genre, every default stage on)
FINISHED = {"revolution": 0, "music2dance": 0, "dual": 0}


def write_song(folder: Path, seconds: float = SONG_S) -> Path:
    """The golden song's first ``seconds`` (a wav) in ``folder``."""
    from dancekit.audio import save_wav, synth

    y = synth.ode_to_joy(sr=SR, bpm=BPM)[: int(seconds * SR)]
    path = Path(folder) / f"ode_{seconds:g}s.wav"
    save_wav(path, y, sr=SR)
    return path


def model_dances(song: Path, *, model: str, cases: dict, **options) -> dict[str, np.ndarray]:
    """The model's own dances (stages off): ``{case: (T, J, 3) float32 positions}``."""
    from dancekit.pipelines import load_pipeline

    pipe = load_pipeline(model)
    return {key: np.asarray(pipe(str(song), seed=seed, genre=genre, beat_sync=False, cleanup=False, **options)
                            .motion.to_positions(), np.float32)
            for key, (genre, seed) in cases.items()}


def finished_dance(song: Path, model: str, seed: int):
    """The :class:`~dancekit.pipelines.base.DanceResult` a user gets: every default stage on."""
    from dancekit.pipelines import load_pipeline

    return load_pipeline(model)(str(song), seed=seed)


def _glb_accessor(gltf, blob: bytes, i: int) -> np.ndarray:
    acc = gltf.accessors[i]
    view = gltf.bufferViews[acc.bufferView]
    dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32, 5121: np.uint8}[acc.componentType]
    n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return np.frombuffer(blob, dtype=dtype, count=acc.count * n, offset=start).reshape(acc.count, n).copy()


def read_bvh_text(path: Path) -> tuple[str, np.ndarray]:
    """``(hierarchy, values)``: the text before the ``MOTION`` line and the ``(T, C)`` channel values."""
    text = Path(path).read_text()
    head, motion = text.split("\nMOTION\n", 1)
    lines = motion.splitlines()
    assert lines[0].startswith("Frames:") and lines[1].startswith("Frame Time:"), lines[:2]
    values = np.array([[float(v) for v in line.split()] for line in lines[2:] if line.strip()])
    return head + "\n" + "\n".join(lines[:2]), values


def read_glb(path: Path) -> dict[str, np.ndarray]:
    """The glb's node names and its animation and skin accessors, keyed as in the module docstring."""
    import pygltflib

    gltf = pygltflib.GLTF2().load(str(path))
    blob = gltf.binary_blob()
    names = [n.name for n in gltf.nodes]
    out = {"glb/nodes": np.asarray(names, dtype=str)}
    anim = gltf.animations[0]
    out["glb/times"] = _glb_accessor(gltf, blob, anim.samplers[0].input)[:, 0]
    for ch in anim.channels:
        key = f"glb/{ch.target.path}/{names[ch.target.node]}"
        out[key] = _glb_accessor(gltf, blob, anim.samplers[ch.sampler].output)
    out["glb/inverse_bind"] = _glb_accessor(gltf, blob, gltf.skins[0].inverseBindMatrices)
    return out


def user_files(motion, folder: Path) -> dict[str, np.ndarray]:
    """The npz, BVH and glb files ``export_motion`` writes from ``motion``, read back (keys: module docstring)."""
    from dancekit.export import export_motion

    paths = export_motion(motion, folder, stem="dance", formats=["npz", "bvh", "glb"])
    npz, bvh, glb = (p for p in paths)
    out = {}
    with np.load(npz, allow_pickle=False) as z:
        for key in z.files:
            a = z[key]
            out[f"npz/{key}"] = a.astype(np.float32) if a.dtype.kind == "f" and a.ndim else a
    hierarchy, values = read_bvh_text(bvh)
    out["bvh/hierarchy"] = np.asarray(hierarchy)
    out["bvh/values"] = values.astype(np.float32)
    out.update(read_glb(glb))
    return out


def finished_record(song: Path, model: str, seed: int, folder: Path) -> dict[str, np.ndarray]:
    """Everything ``finished_<model>.npz`` holds: the notes and :func:`user_files` of the finished dance."""
    result = finished_dance(song, model, seed)
    out = {"notes": np.asarray(list(result.notes), dtype=str)}
    out.update(user_files(result.motion, Path(folder)))
    return out


def main(argv: list[str]) -> int:
    which = set(argv) or {"model", "finished"}
    with tempfile.TemporaryDirectory() as tmp:
        song = write_song(Path(tmp))
        if "model" in which:
            np.savez_compressed(HERE / "default_model.npz",
                                **model_dances(song, model="revolution", cases=MODEL_CASES, variety=False))
            np.savez_compressed(HERE / "default_model_variety.npz",
                                **model_dances(song, model="revolution", cases=VARIETY_CASES, variety=True))
            np.savez_compressed(HERE / "music2dance.npz", **model_dances(song, model="music2dance", cases=M2D_CASES))
        if "finished" in which:
            song = write_song(Path(tmp), FINISHED_S)
            for model, seed in FINISHED.items():
                record = finished_record(song, model, seed, Path(tmp) / model)
                np.savez_compressed(HERE / f"finished_{model}.npz", **record)
                print(f"finished_{model}.npz: {len(record)} arrays; {'; '.join(record['notes'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
