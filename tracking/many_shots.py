"""Many shots of a project tracked at once on Dask: ``facestudio track-many`` (one task per shot).

:func:`track_many` sends one task per shot (:func:`track_shot`) to Dask workers — an embedded
:class:`distributed.LocalCluster` of processes on this machine, or an existing cluster given its
scheduler's address — and gathers what each shot did into a summary (``track_many.json`` and
``track_many.csv``, :func:`write_summary`).

Why Dask (``dask.distributed``), chosen over Ray: a tenth of the install; one API for an embedded
``LocalCluster`` of processes and a cluster (``Client(address)``); per-task retries, and a task whose
worker died is rescheduled on another.

* **A shot** is :func:`tracking.run.track_video` run in a worker: the same resumable, cancel-safe run
  as ``facestudio track``, its results in the same folder (``<out>/track_<video stem>``, default
  ``<project folder>/results``), every file written atomically by :mod:`tracking.track_result`.
* **Workers** are processes with one thread each (``threads_per_worker=1``). The GL context is the
  renderer's (:func:`photomodel.rendering.renderer.get_renderer`: one per thread), made by the first
  shot a worker tracks and kept for its next ones; the parent process never makes one. The face
  model of the project is built once per worker and kept too (:func:`_worker_model`).
* **Threads**: each worker pins its own thread use (:func:`pin_threads`, run by the worker plugin
  :class:`PinThreads` as a worker starts, before its GL context exists): llvmpipe's
  ``LP_NUM_THREADS``, OpenCV's thread pool and BLAS (:mod:`threadpoolctl`), ``cores // workers``
  each on a ``LocalCluster``, so N workers share the cores instead of fighting over them. The
  single-shot command leaves them alone and uses every core.
* **Faults**: a worker that dies mid-shot (killed, out of memory) has its task rescheduled on another
  worker (up to ``distributed.scheduler.allowed-failures`` times); the new attempt continues after
  the frames the dead one saved, so the shot's results equal an uninterrupted run's
  (:func:`tracking.run.track_video` resumes exactly). An unexpected exception is retried
  ``retries`` times. A :class:`~photomodel.errors.FaceStudioError` (a corrupt or missing video, a
  missing first pose) fails its shot at once, with its message; the other shots finish.
* **Reruns**: a shot whose folder holds its finished results (:func:`finished`) is skipped; an
  unfinished one continues where it stopped.
* **Cancelling**: :func:`track_many`'s ``stop()`` sets a Dask :class:`distributed.Event` that every
  shot checks (at most every :data:`STOP_POLL_S` seconds): each saves its frames and ends.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import os
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
from distributed import Client, Event, LocalCluster, get_worker
from distributed.diagnostics.plugin import WorkerPlugin
from threadpoolctl import threadpool_limits

from photomodel.errors import FaceStudioError
from photomodel.exchange.files import atomic_write_bytes
from photomodel.project import load_project
from tracking.arkit_face import tracking_face_model
from tracking.run import SAVE_EVERY, track_video
from tracking.track_result import load_track_results

__all__ = [
    "SUMMARY_JSON",
    "SUMMARY_CSV",
    "EXIT_AFTER_ENV",
    "Shot",
    "ShotResult",
    "BatchProgress",
    "BatchResult",
    "plan_shots",
    "finished",
    "pin_threads",
    "PinThreads",
    "track_shot",
    "track_many",
    "write_summary",
]

SUMMARY_JSON = "track_many.json"
SUMMARY_CSV = "track_many.csv"
#: Fault injection for tests and the benchmark: ``"K:FLAG"`` makes the first worker that tracks K
#: frames of one attempt create the file FLAG (holding the video's path) and exit at once
#: (``os._exit``), as a killed worker would; FLAG existing disarms it.
EXIT_AFTER_ENV = "FACESTUDIO_TRACK_MANY_EXIT_AFTER"
#: A shot asks whether the batch was stopped at most this often (one scheduler round trip).
STOP_POLL_S = 1.0
_SUMMARY_COLUMNS = [
    "video",
    "out_dir",
    "status",
    "frames",
    "tracked",
    "resumed_from",
    "complete",
    "seconds",
    "fps",
    "diverged",
    "mean_rms",
    "worker",
    "error",
]


@dataclass
class Shot:
    """One video of a batch and the folder its results go to (``<out root>/track_<video stem>``)."""

    video: Path
    out_dir: Path


@dataclass
class ShotResult:
    """What became of one shot.

    ``status``: ``"tracked"`` (by this batch; ``complete`` as :class:`tracking.run.TrackResult`'s),
    ``"skipped"`` (finished before), ``"cancelled"`` (stopped; its frames saved) or ``"failed"``
    (``error`` says why). ``frames``: frames in its results; ``tracked``: frames tracked by this
    batch's last attempt, after ``resumed_from`` frames already there; ``seconds``: its fitting time.
    """

    video: str
    out_dir: str
    status: str
    frames: int = 0
    tracked: int = 0
    resumed_from: int = 0
    complete: bool = False
    seconds: float = 0.0
    diverged: int = 0
    mean_rms: float | None = None
    worker: str | None = None
    error: str | None = None

    @property
    def fps(self) -> float:
        return self.tracked / self.seconds if self.seconds > 0 else 0.0


@dataclass
class BatchProgress:
    """How far a batch is, as :func:`track_many` tells its ``progress``: shots ended (tracked,
    skipped, failed or cancelled) of ``shots``, ``failed`` among them, frames tracked by all workers
    so far, ``seconds`` since the batch started (cluster start-up included), and the
    :class:`ShotResult` of each shot this batch ran, in the order they ended (``finished``)."""

    shots: int
    ended: int = 0
    failed: int = 0
    frames: int = 0
    seconds: float = 0.0
    finished: list = field(default_factory=list)  # the ShotResults of the shots ended so far, as they ended

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0


@dataclass
class BatchResult:
    """What :func:`track_many` did: one :class:`ShotResult` per shot (in the order given), the
    folder of the summary, the workers (count, scheduler address), ``startup_s`` (starting or
    reaching the cluster), ``seconds`` (the whole batch, start-up included), the summary files."""

    shots: list[ShotResult]
    out_root: Path
    workers: int
    scheduler: str
    startup_s: float
    seconds: float
    cancelled: bool = False
    files: dict = field(default_factory=dict)

    @property
    def failed(self) -> int:
        return sum(s.status == "failed" for s in self.shots)

    @property
    def tracked_frames(self) -> int:
        return sum(s.tracked for s in self.shots)

    def summary(self) -> dict:
        """The JSON-able summary (``track_many.json``): the batch's figures and every shot."""
        return {
            "out_root": str(self.out_root),
            "workers": self.workers,
            "scheduler": self.scheduler,
            "shots": len(self.shots),
            "failed": self.failed,
            "cancelled": self.cancelled,
            "tracked_frames": self.tracked_frames,
            "startup_s": round(self.startup_s, 3),
            "seconds": round(self.seconds, 3),
            "fps": round(self.tracked_frames / self.seconds, 3) if self.seconds > 0 else 0.0,
            "by_status": {
                k: sum(s.status == k for s in self.shots) for k in ("tracked", "skipped", "cancelled", "failed")
            },
            "shot_results": [asdict(s) | {"fps": round(s.fps, 3)} for s in self.shots],
        }


def plan_shots(
    project_path: str | os.PathLike, videos: Sequence[str | os.PathLike], out_root: str | os.PathLike | None = None
) -> list[Shot]:
    """The shots of ``videos``: each with its results folder ``<out_root>/track_<video stem>``
    (``out_root`` default ``<project folder>/results``: where ``facestudio track`` puts them).

    Raises FaceStudioError when no video is given or two videos share a stem (one folder for both).
    A missing or corrupt video is not refused here: its shot fails alone.
    """
    if not videos:
        raise FaceStudioError("no videos to track: give at least one video file or frame folder")
    root = Path(out_root).absolute() if out_root is not None else Path(project_path).absolute().parent / "results"
    shots, seen = [], {}
    for v in videos:
        video = Path(v).absolute()
        stem = video.stem
        if stem in seen:
            raise FaceStudioError(
                f"{seen[stem]} and {video} would share the results folder {root / f'track_{stem}'}: "
                f"rename one, or track them in two batches with different --out"
            )
        seen[stem] = video
        shots.append(Shot(video, root / f"track_{stem}"))
    return shots


def finished(shot: Shot, max_frames: int | None, overlay: bool = True) -> ShotResult | None:
    """The shot's finished results as a ``"skipped"`` :class:`ShotResult`, or None when it is still
    to track (or to continue): finished means the whole video (or its first ``max_frames``) is in
    ``track.json``, and the overlay video is written if ``overlay``. Unreadable results are not
    finished (the shot's run names the problem)."""
    try:
        doc = load_track_results(shot.out_dir)
    except FaceStudioError:
        return None
    if doc is None or not doc["frames"]:
        return None
    n = len(doc["frames"])
    if not (doc.get("complete") or (max_frames is not None and n >= max_frames)):
        return None
    if overlay and not (shot.out_dir / "overlay.mp4").is_file():
        return None
    rms = [f["rms"] for f in doc["frames"]]
    return ShotResult(
        str(shot.video),
        str(shot.out_dir),
        "skipped",
        frames=n,
        complete=bool(doc.get("complete")),
        diverged=sum(bool(f["diverged"]) for f in doc["frames"]),
        mean_rms=float(sum(rms) / len(rms)),
    )


# ----------------------------------------------------------------------------- in the workers

_BLAS_LIMITS: list = []


def pin_threads(threads: int) -> None:
    """Limit this process to ``threads`` threads of llvmpipe, OpenCV and BLAS (a worker's share of
    the cores). ``LP_NUM_THREADS`` counts only for GL contexts made after this call: a worker calls
    it before its first shot."""
    threads = max(1, int(threads))
    os.environ["LP_NUM_THREADS"] = str(threads)
    cv2.setNumThreads(threads)
    _BLAS_LIMITS[:] = [threadpool_limits(limits=1, user_api="blas")]  # kept: the limit lasts while it lives


class PinThreads(WorkerPlugin):
    """Worker plugin: :func:`pin_threads` as each worker starts (a restarted one too)."""

    name = "facestudio-pin-threads"

    def __init__(self, threads: int):
        self.threads = int(threads)

    def setup(self, worker) -> None:
        pin_threads(self.threads)


_MODELS: dict = {}


def _worker_model(project_path: Path, expressions: tuple | None):
    """The face model ``track`` would use (:func:`tracking.arkit_face.tracking_face_model`: the rig's
    ARKit shapes when the project has a rig, else the photographed expressions), built once per
    worker process for a project file as it is now, and its source sentence."""
    key = (str(project_path), project_path.stat().st_mtime_ns, expressions)
    if key not in _MODELS:
        _MODELS.clear()
        names = None if expressions is None else list(expressions)
        model, source, _basis = tracking_face_model(load_project(project_path), None, names)
        _MODELS[key] = (model, source)
    return _MODELS[key]


def _exit_hook(video: Path) -> Callable[[int], None]:
    """The fault injection of :data:`EXIT_AFTER_ENV`: called with the frames this attempt tracked."""
    spec = os.environ.get(EXIT_AFTER_ENV, "")
    if ":" not in spec:
        return lambda tracked: None
    k, flag = spec.split(":", 1)

    def maybe_exit(tracked: int) -> None:
        if tracked >= int(k) and not os.path.exists(flag):
            try:
                with open(flag, "x") as f:  # one worker only
                    f.write(str(video))
            except FileExistsError:
                return
            os._exit(70)

    return maybe_exit


def _reporter(topic: str | None, index: int, video: Path, stop_name: str | None):
    """``progress(done, total)`` and ``cancel()`` for :func:`tracking.run.track_video` in a worker:
    one event per frame on ``topic``; stopped once the batch's Event ``stop_name`` is set."""
    worker = get_worker() if topic or stop_name else None
    stop = Event(stop_name) if stop_name else None
    hook = _exit_hook(video)
    state = {"tracked": 0, "asked": time.monotonic(), "stopped": False}

    def progress(done: int, total: int | None) -> None:
        state["tracked"] += 1
        if topic:
            worker.log_event(topic, {"shot": index, "done": done, "total": total})
        hook(state["tracked"])

    def cancel() -> bool:
        now = time.monotonic()
        if stop is not None and now - state["asked"] >= STOP_POLL_S:
            state["asked"] = now
            state["stopped"] = stop.is_set()
        return state["stopped"]

    return progress, cancel


def track_shot(
    project_path: str,
    video: str,
    out_dir: str,
    *,
    max_frames: int | None = None,
    expressions: tuple | None = None,
    overlay: bool = True,
    save_every: int = SAVE_EVERY,
    index: int = 0,
    topic: str | None = None,
    stop_name: str | None = None,
) -> ShotResult:
    """Track one shot in this (worker) process: :func:`tracking.run.track_video` into ``out_dir``,
    continuing what is there. A FaceStudioError (bad video, first pose, project) becomes a
    ``"failed"`` result naming it; other exceptions propagate (Dask retries them)."""
    project_path, video_path, out = Path(project_path), Path(video), Path(out_dir)
    try:
        worker = get_worker().address
    except ValueError:  # not in a worker (sequential use in this process)
        worker = None
    try:
        model, source = _worker_model(project_path, expressions)
        progress, cancel = _reporter(topic, index, video_path, stop_name)
        res = track_video(
            project_path,
            video_path,
            out,
            model=model,
            model_source=source,
            max_frames=max_frames,
            overlay=overlay,
            save_every=save_every,
            progress=progress,
            cancel=cancel,
            segments=1,  # the shots are the parallel work here (and a Dask worker may not start processes)
        )
    except FaceStudioError as exc:
        return ShotResult(video, out_dir, "failed", worker=worker, error=f"{type(exc).__name__}: {exc}")
    rms = [f["rms"] for f in res.frames]
    return ShotResult(
        video,
        out_dir,
        "cancelled" if res.cancelled else "tracked",
        frames=len(res.frames),
        tracked=res.tracked,
        resumed_from=res.resumed_from,
        complete=res.complete,
        seconds=res.seconds,
        diverged=res.diverged,
        mean_rms=float(sum(rms) / len(rms)) if rms else None,
        worker=worker,
    )


# ----------------------------------------------------------------------------- in the parent


def _connect(workers: int | None, scheduler: str | None, threads: int | None, shots: int):
    """A client of a new ``LocalCluster`` (``workers`` processes, default one per core up to the
    shots) or of the cluster at ``scheduler``, its workers' threads pinned; returns (client,
    cluster or None, worker count)."""
    if scheduler:
        if workers is not None:
            raise FaceStudioError(
                "--workers is for the embedded cluster: with --scheduler the cluster's own "
                "workers track the shots (start more with `dask worker`)"
            )
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise FaceStudioError(
                f"no Dask scheduler answers at {scheduler} ({exc}); start one with "
                f"`dask scheduler` and workers with `dask worker {scheduler}`"
            ) from exc
        client.register_plugin(PinThreads(threads or 1))
        return client, None, len(client.scheduler_info()["workers"])
    cores = os.cpu_count() or 1
    n = workers if workers is not None else max(1, min(cores, shots))
    if n < 1:
        raise FaceStudioError(f"--workers {n}: at least one worker")
    per = threads or max(1, cores // n)
    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        silence_logs=logging.ERROR,
        env={"LP_NUM_THREADS": str(per)},
    )
    client = Client(cluster)
    client.register_plugin(PinThreads(per))
    return client, cluster, n


def _submit(
    client: Client,
    project: Path,
    shots: list[Shot],
    todo: list[int],
    options: dict,
    retries: int,
    topic: str,
    stop_name: str,
) -> dict:
    """One task per shot still to track; returns {future: shot index}."""
    futures = {}
    for i in todo:
        s = shots[i]
        f = client.submit(
            track_shot,
            str(project),
            str(s.video),
            str(s.out_dir),
            index=i,
            topic=topic,
            stop_name=stop_name,
            retries=retries,
            pure=False,
            key=f"track-{i}-{s.video.name}-{topic}",
            **options,
        )
        futures[f] = i
    return futures


def _outcome(future, shot: Shot) -> ShotResult:
    """The :class:`ShotResult` of a finished task; a task that raised (or whose workers all died) is
    a ``"failed"`` shot naming the cause."""
    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 - whatever ended the shot is its reported cause
        return ShotResult(str(shot.video), str(shot.out_dir), "failed", error=f"{type(exc).__name__}: {exc}")


def track_many(
    project_path: str | os.PathLike,
    videos: Sequence[str | os.PathLike],
    out_root: str | os.PathLike | None = None,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    threads: int | None = None,
    max_frames: int | None = None,
    expressions: Sequence[str] | None = None,
    overlay: bool = True,
    save_every: int = SAVE_EVERY,
    retries: int = 1,
    progress: Callable[[BatchProgress], None] | None = None,
    stop: Callable[[], bool] | None = None,
    poll_s: float = 0.25,
) -> BatchResult:
    """Track every video of ``videos`` with the project's face model, one Dask task per shot.

    Parameters
    ----------
    project_path : the project file; on a cluster, a path every worker reads (a shared folder).
    videos : video files or frame folders; results in ``<out_root>/track_<stem>`` (:func:`plan_shots`).
    workers : processes of the embedded ``LocalCluster`` (default one per core, at most one per shot).
    scheduler : a Dask scheduler's address (``tcp://host:8786``): use its workers instead.
    threads : threads each worker may use (llvmpipe, OpenCV); default cores // workers (1 on a cluster).
    max_frames, expressions, overlay, save_every : as :func:`tracking.run.track_video` takes them.
    retries : how often a shot that raised something unexpected is tried again.
    progress : ``progress(BatchProgress)``, called every ``poll_s`` seconds and as shots end.
    stop : ``stop() -> bool``; True asks every running shot to save its frames and end (``"cancelled"``).

    Returns
    -------
    BatchResult, its summary written (:func:`write_summary`). A KeyboardInterrupt closes the
    embedded cluster at once; every shot keeps the frames it saved (a rerun continues).
    """
    t0 = time.perf_counter()
    project = Path(project_path).absolute()
    shots = plan_shots(project, videos, out_root)
    results: list[ShotResult | None] = [finished(s, max_frames, overlay) for s in shots]
    todo = [i for i, r in enumerate(results) if r is None]
    state = BatchProgress(len(shots), ended=len(shots) - len(todo))
    client = cluster = None
    n, address, startup = 0, scheduler or "", 0.0
    try:
        if todo:
            client, cluster, n = _connect(workers, scheduler, threads, len(todo))
            address, startup = client.scheduler.address, time.perf_counter() - t0
            options = {
                "max_frames": max_frames,
                "overlay": overlay,
                "save_every": save_every,
                "expressions": None if expressions is None else tuple(expressions),
            }
            _run_tasks(client, project, shots, todo, options, retries, results, state, t0, progress, stop, poll_s)
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    done = BatchResult(
        results,
        shots[0].out_dir.parent,
        n,
        address,
        startup,
        time.perf_counter() - t0,  # type: ignore[arg-type]
        cancelled=any(r.status == "cancelled" for r in results),
    )
    done.files = write_summary(done)
    return done


def _run_tasks(client, project, shots, todo, options, retries, results, state, t0, progress, stop, poll_s) -> None:
    """Submit the shots ``todo``, follow them (progress events, stop) and fill ``results``."""
    topic, stop_name = f"facestudio-track-many-{uuid.uuid4().hex}", f"facestudio-stop-{uuid.uuid4().hex}"

    def on_event(event) -> None:  # runs in the client's event loop
        state.frames += 1

    client.subscribe_topic(topic, on_event)
    futures = _submit(client, project, shots, todo, options, retries, topic, stop_name)
    stopping = False
    while futures:
        for f in [f for f in futures if f.done()]:
            i = futures.pop(f)
            results[i] = _outcome(f, shots[i])
            state.finished.append(results[i])
            state.ended += 1
            state.failed += results[i].status == "failed"
        if stop is not None and not stopping and stop():
            Event(stop_name, client=client).set()
            stopping = True
        state.seconds = time.perf_counter() - t0
        if progress is not None:
            progress(state)
        if futures:
            time.sleep(poll_s)
    client.unsubscribe_topic(topic)


def write_summary(result: BatchResult) -> dict[str, Path]:
    """``track_many.json`` (:meth:`BatchResult.summary`) and ``track_many.csv`` (a row per shot)
    into the batch's results folder, atomically; returns {"json": path, "csv": path}."""
    root = result.out_root
    root.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_SUMMARY_COLUMNS)
    for s in result.shots:
        row = asdict(s) | {"fps": round(s.fps, 3)}
        w.writerow(["" if row[c] is None else row[c] for c in _SUMMARY_COLUMNS])
    files = {"json": root / SUMMARY_JSON, "csv": root / SUMMARY_CSV}
    atomic_write_bytes(files["csv"], buf.getvalue().encode())
    summary = result.summary() | {"files": {k: str(v) for k, v in files.items()}}
    atomic_write_bytes(files["json"], json.dumps(summary, indent=1).encode())
    return files
