"""The multilinear model as a file: built once from the model people, kept, loaded.

    .venv/bin/python -m photomodel.people.model_file [--people 100] [--out PATH]

builds the model of :mod:`photomodel.people.multilinear` from ``--people`` ICT identities of
:mod:`photomodel.people.dataset` (their set ``"model"``; built and cached first if needed) and writes it
(default ``cache_dir()/people-multilinear-<people>-<versions>.npz``). Ranks :data:`MODEL_RANKS`: the
vertex mode truncated to 600 components, the identity and expression modes kept whole (100 and 52
knobs). Measured on the held-out cloning benchmark (the seed's route in the model's coordinates, before
:mod:`photomodel.people.rig_clone`, which gives 0.073 mm with this model): 30 people and 300 vertex
components gave 0.24 mm, 100 people and 300 gave 0.216 mm, 100 and 600 gave 0.200 mm (displacement
copy 0.257 mm). Size: the
vertex basis dominates, ``3n × 600`` float32 (56 MB) + the core ``600 × 100 × 52`` (12 MB): about
68 MB for the generic mesh's 8101 vertices. Building it: ~15 min of rigs for 100 people (cached), then
~4 min. It is never rebuilt at run time by the studio; the benchmark builds it when the file is missing.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from photomodel.data.cache import cache_dir
from photomodel.people.dataset import DATASET_VERSION, EXPRESSIONS, load_people
from photomodel.people.multilinear import MultilinearModel, build_model

__all__ = ["MODEL_RANKS", "MODEL_PEOPLE", "model_path", "load_or_build_model", "main"]

#: (vertex, identity, expression) ranks; None keeps the mode whole.
MODEL_RANKS = (600, None, None)
#: People of the default model.
MODEL_PEOPLE = 100


def model_path(people: int) -> Path:
    """The default model file of ``people`` model people."""
    ranks = "x".join(str(r) for r in MODEL_RANKS if r is not None)
    return cache_dir() / f"people-multilinear-{people}-{ranks}-{DATASET_VERSION}.npz"


def load_or_build_model(people: int = MODEL_PEOPLE, path: Path | None = None) -> tuple[MultilinearModel, dict]:
    """The model (loaded, or built and written) and ``{ranks, file_mb, file, built_s}``."""
    path = path or model_path(people)
    built = None
    if path.is_file():
        model = MultilinearModel.load(path)
    else:
        t0 = time.perf_counter()
        data = load_people("model", people)
        model = build_model(data.tensor(), MODEL_RANKS, EXPRESSIONS, data.names)
        model.save(path)
        built = round(time.perf_counter() - t0, 1)
    info = {"ranks": list(model.ranks), "file_mb": round(path.stat().st_size / 2**20, 1), "file": str(path)}
    if built is not None:
        info["built_s"] = built
    return model, info


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="build the multilinear model file")
    ap.add_argument("--people", type=int, default=MODEL_PEOPLE)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    path = args.out or model_path(args.people)
    if path.is_file():
        path.unlink()  # rebuild
    _, info = load_or_build_model(args.people, path)
    print(info)
    return 0


if __name__ == "__main__":
    sys.exit(main())
