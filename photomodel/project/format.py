"""The project file's format constants: its name and version, the file suffix, the built-in mesh's
name and the click sources — what the data model (:mod:`photomodel.project.datamodel`), the codec
and the validation (:mod:`photomodel.project.validate`) share, kept apart so that none of them
imports another for a constant."""

from __future__ import annotations

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "CLICK_SOURCES", "FILE_SUFFIX", "BUILTIN_MESH"]

FORMAT_NAME = "facestudio-project"
#: The version this Face Studio writes; it reads every version from 1 up to this one.
#: History (``docs/project-format.md``, "Versioning"):
#:
#: * 1 — the first format.
#: * 2 — a photo may name its ``camera_group`` (photos taken with one camera and lens share one
#:   focal length). Upgrading a version-1 file: nothing to do (no photo has a group).
#: * 3 — a photo may say which of its clicks were placed automatically (``click_sources``:
#:   feature → ``{"source": "auto", "confidence": c}``). Upgrading: nothing to do (every click
#:   of an older file was made by hand, source ``"user"``).
#: * 4 — a project may hold a ``rig``: ARKit-style blend shapes on the fitted neutral
#:   (``facestudio rig``; the displacements in a file beside the project). Upgrading: nothing to
#:   do (an older project has no rig).
#: * 5 — a photo may say which of its curves were drawn automatically (``curve_sources``:
#:   curve → ``"auto"``). Upgrading: nothing to do (every curve of an older file was drawn by
#:   hand).
#: * 6 — a project may reference other people's projects (``people``: paths of other
#:   ``*.facestudio.json`` files, relative to this one's folder), e.g. the people whose performances
#:   were cloned onto this face (``facestudio clone``, the studio's *Clone from another project…*).
#:   Upgrading: nothing to do (an older project references nobody).
FORMAT_VERSION = 6
#: Where a click came from: the artist (``"user"``, the default) or the landmark detector.
CLICK_SOURCES = ("user", "auto")
FILE_SUFFIX = ".facestudio.json"
BUILTIN_MESH = "builtin:template-v1"
