"""``facestudio sample-data``: the sample data fetched, verified and cached; its folder printed.

    facestudio sample-data

The cache folder is ``$FACESTUDIO_CACHE``, else ``$XDG_CACHE_HOME/facestudio``, else
``~/.cache/facestudio`` (:mod:`photomodel.data.fetch`).
"""

from __future__ import annotations

from photomodel.samples.sample_data import sample_data_dir

NAME = "sample-data"
DESCRIPTION = (
    "Fetch the sample data Face Studio is tested with (the menpo3d 0.8.6 source distribution's face "
    "mesh, photo and landmarks, through pip), check every file's SHA-256, keep them in the cache "
    "folder ($FACESTUDIO_CACHE, else ~/.cache/facestudio) and print that folder. Run once; later "
    "runs only verify the files."
)


def run(args) -> int:
    print(sample_data_dir())
    return 0


def add_parser(sub) -> None:
    sub.add_parser(NAME, help="fetch, verify and cache the sample data; print its folder", description=DESCRIPTION)
