"""A Tessera farm from Python: submit a scene, watch, status, cancel and fetch its frames
over the coordinator's gRPC API (proto/tessera/v1/tessera.proto).

It behaves like the `tessera` CLI (cli/farm_client.cpp): the same environment
variables, the same bundle, the same waits for a coordinator that is slow or restarting,
and every failed call raises FarmError with the gRPC status code.
"""

from __future__ import annotations

import contextlib
import datetime
import enum
import hashlib
import itertools
import os
import time
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import (
    Any,
    BinaryIO,
    Callable,
    Iterable,
    Iterator,
    List,
    Optional,
    Tuple,
    TypeVar,
    Union,
)

import grpc

from . import bundle as _bundle

try:
    from .v1 import tessera_pb2 as pb
    from .v1 import tessera_pb2_grpc as pb_grpc
except ImportError as e:  # running from the source tree, or an unbuilt build tree
    raise ImportError(
        "tessera: the generated gRPC stubs (tessera.v1.tessera_pb2) are missing: build them "
        "with `cmake --build build --target tessera_python` and put build/python on "
        f"PYTHONPATH ({e})"
    ) from e

PathLike = Union[str, "os.PathLike[str]"]

DEFAULT_ADDRESS = "127.0.0.1:50051"
# Unary calls; a submission may load the scene on the coordinator to check it.
CALL_TIMEOUT_S = 60.0
SUBMIT_TIMEOUT_S = 300.0
# How long a call waits for a coordinator that does not answer yet (cli/farm_client.cpp).
DEFAULT_CONNECT_TIMEOUT_S = 30.0
# Bytes per PutBlob message (common/blob_client.h's kBlobChunkBytes).
_CHUNK_BYTES = 1 << 20
# The trailing metadata in which the coordinator sends a frame file's SHA-256.
_FRAME_SHA256_KEY = "tessera-sha256"
# Stands for the client's call_timeout where None means no deadline.
_CALL_TIMEOUT = object()


class FarmError(Exception):
    """A call the coordinator refused or that could not reach it.

    `code` is the grpc.StatusCode (NOT_FOUND, INVALID_ARGUMENT, UNAUTHENTICATED,
    UNAVAILABLE, DEADLINE_EXCEEDED, DATA_LOSS, ...), `details` the coordinator's message
    and `context` what the client was doing. str() reads "getting job 'job-9': NOT_FOUND:
    no job job-9"."""

    def __init__(self, code: grpc.StatusCode, details: str, context: str = ""):
        self.code = code
        self.details = details
        self.context = context
        text = f"{code.name}: {details}"
        super().__init__(f"{context}: {text}" if context else text)

    def __reduce__(self) -> Any:  # pickled with its fields (multiprocessing)
        return (FarmError, (self.code, self.details, self.context))


class JobState(str, enum.Enum):
    """A job's state; a str, so `state == "DONE"` also holds."""

    UNSPECIFIED = "UNSPECIFIED"
    QUEUED = "QUEUED"
    RUNNING = "RUNNING"
    DONE = "DONE"
    FAILED = "FAILED"
    CANCELLED = "CANCELLED"

    @property
    def finished(self) -> bool:
        return self in (JobState.DONE, JobState.FAILED, JobState.CANCELLED)


class FrameState(str, enum.Enum):
    UNSPECIFIED = "UNSPECIFIED"
    PENDING = "PENDING"
    RENDERING = "RENDERING"
    DONE = "DONE"  # its EXR is written
    FAILED = "FAILED"


def _enum(kind: type, proto_enum: Any, value: int, prefix: str) -> Any:
    try:
        return kind(proto_enum.Name(value)[len(prefix) :])
    except ValueError:  # a state newer than this client
        return kind.UNSPECIFIED


T = TypeVar("T")


def _copy(cls: type, message: Any, **converted: Any) -> Any:
    """A dataclass from the proto message's fields of the same names (`converted` for
    those that need more than a copy; `proto` gets the message itself)."""
    values = {}
    for f in fields(cls):
        if f.name in converted:
            values[f.name] = converted[f.name]
        elif f.name == "proto":
            values[f.name] = message
        else:
            values[f.name] = getattr(message, f.name)
    return cls(**values)


def _utc(unix_ms: int) -> Optional[datetime.datetime]:
    if unix_ms <= 0:
        return None
    return datetime.datetime.fromtimestamp(unix_ms / 1000, tz=datetime.timezone.utc)


@dataclass(frozen=True)
class FrameStatus:
    frame: int
    state: FrameState
    tasks_done: int  # of all its stages
    tasks_total: int
    exr_path: str  # on the coordinator's disk, once done
    stage: str  # the stage under way: "photons", "irradiance-2", "render"
    stage_label: str  # for people: "irradiance pass 2/3"
    stage_done: int
    stage_total: int

    @staticmethod
    def from_proto(m: Any) -> "FrameStatus":
        state = _enum(FrameState, pb.FrameState, m.state, "FRAME_STATE_")
        return _copy(FrameStatus, m, state=state)

    @property
    def stage_progress(self) -> str:
        """"photons 12/16", "irradiance pass 2/3 (40/64)", "render 130/256"; "" if the
        coordinator did not say (as `tessera status` shows it)."""
        if not self.stage:
            return ""
        label = self.stage_label or self.stage
        count = f"{self.stage_done}/{self.stage_total}"
        return f"{label} ({count})" if "/" in label else f"{label} {count}"


@dataclass(frozen=True)
class TaskFailure:
    frame: int
    task_index: int
    worker: str
    message: str
    attempt: int
    stage: str
    log_tail: str  # the worker's last log lines while it ran the task
    task: int  # the task's number in its job (Client.log(job, task=...))

    @staticmethod
    def from_proto(m: Any) -> "TaskFailure":
        return _copy(TaskFailure, m)


@dataclass(frozen=True)
class JobLogEntry:
    """One entry of a job's log (Client.log): what happened to the job, a frame or a task."""

    at_unix_ms: int
    # "submitted", "done", "failed", "expired" (a task's attempt), "merged", "frame",
    # "priority", "cancelled", "retried", "job-failed", "job-done", "requeued"
    kind: str
    frame: int  # -1 for job-wide entries
    stage: str
    task_index: int  # in its stage; -1 if none
    task: int  # the task's number in the job; -1 if none
    worker: str
    attempt: int
    message: str
    log_tail: str  # a failure's worker log lines
    leased_unix_ms: int  # an attempt's: when its lease was granted (0 if unknown)

    @staticmethod
    def from_proto(m: Any) -> "JobLogEntry":
        return _copy(JobLogEntry, m)

    @property
    def at(self) -> Optional[datetime.datetime]:
        return _utc(self.at_unix_ms)


@dataclass(frozen=True)
class JobStatus:
    job_id: str
    name: str
    state: JobState
    priority: int
    tasks_done: int
    tasks_total: int
    frames: Tuple[FrameStatus, ...]
    error: str  # why the job failed
    failures: Tuple[TaskFailure, ...]  # most recent first, at most 20
    submitted_unix_ms: int
    finished_unix_ms: int  # 0 while unfinished
    width: int
    height: int
    spp: int
    leases_granted: int
    farm_problem: str  # non-empty while the farm cannot progress (a full disk)
    proto: Any = field(repr=False, compare=False)  # the tessera.v1.JobStatus message

    @staticmethod
    def from_proto(m: Any) -> "JobStatus":
        return _copy(
            JobStatus,
            m,
            state=_enum(JobState, pb.JobState, m.state, "JOB_STATE_"),
            frames=tuple(FrameStatus.from_proto(f) for f in m.frames),
            failures=tuple(TaskFailure.from_proto(f) for f in m.failures),
        )

    @property
    def finished(self) -> bool:
        return self.state.finished

    @property
    def progress(self) -> float:
        """Tasks done over all tasks, in [0, 1]."""
        return self.tasks_done / self.tasks_total if self.tasks_total > 0 else 0.0

    @property
    def frames_done(self) -> int:
        return sum(f.state == FrameState.DONE for f in self.frames)

    @property
    def submitted(self) -> Optional[datetime.datetime]:
        return _utc(self.submitted_unix_ms)

    @property
    def finished_at(self) -> Optional[datetime.datetime]:
        return _utc(self.finished_unix_ms)


@dataclass(frozen=True)
class JobEvent:
    """A change in a job, as `Client.watch` yields it."""

    status: JobStatus  # the job as of this event
    message: str  # for people: "frame 3 done", "task 12 failed on w1: ..."; may be ""

    @property
    def state(self) -> JobState:
        return self.status.state

    @property
    def progress(self) -> float:
        return self.status.progress


@dataclass(frozen=True)
class WorkerStatus:
    worker_id: str
    name: str
    state: str  # "idle", "busy", "put aside", "silent", "disabled", "draining"
    threads: int
    tasks_leased: int
    last_seen_unix_ms: int
    failures_in_a_row: int
    put_aside_until_unix_ms: int
    disabled: bool  # by an operator (Client.set_worker_enabled)
    current_task: str  # "job-7 frame 3 render 12/64"; "" when idle
    samples_done: int  # the worker's totals since it started
    rays_traced: int
    samples_per_second: float  # over its last heartbeats
    rays_per_second: float
    tasks_done: int  # since the coordinator started
    tasks_failed: int

    @staticmethod
    def from_proto(m: Any) -> "WorkerStatus":
        return _copy(WorkerStatus, m)


@dataclass(frozen=True)
class Tls:
    """How to reach a coordinator over TLS (docs/security.md)."""

    ca_file: Optional[PathLike] = None  # the CA that signed its certificate; None: system roots
    cert_file: Optional[PathLike] = None  # a client certificate (mutual TLS), with key_file
    key_file: Optional[PathLike] = None
    server_name: Optional[str] = None  # the name its certificate carries, if not the host's

    @staticmethod
    def from_environment() -> Optional["Tls"]:
        """From $TESSERA_TLS_CA (TLS only when it is set), $TESSERA_TLS_CERT,
        $TESSERA_TLS_KEY and $TESSERA_TLS_SERVER_NAME, like the CLI."""
        ca = os.environ.get("TESSERA_TLS_CA")
        if not ca:
            return None
        return Tls(
            ca_file=ca,
            cert_file=os.environ.get("TESSERA_TLS_CERT") or None,
            key_file=os.environ.get("TESSERA_TLS_KEY") or None,
            server_name=os.environ.get("TESSERA_TLS_SERVER_NAME") or None,
        )


def _read_token_file(path: PathLike) -> str:
    token = Path(path).read_text(encoding="utf-8").strip()
    if not token:
        raise ValueError(f"{path} is empty: it should hold a token")
    return token


def _resolve_token(token: Optional[str], token_file: Optional[PathLike]) -> Optional[str]:
    if token:
        return token.strip()
    if token_file:
        return _read_token_file(token_file)
    env = os.environ.get("TESSERA_TOKEN", "").strip()
    if env:
        return env
    env_file = os.environ.get("TESSERA_TOKEN_FILE")
    return _read_token_file(env_file) if env_file else None


def _resolve_tls(tls: Union[None, bool, PathLike, Tls]) -> Optional[Tls]:
    if tls is None:
        return Tls.from_environment()
    if tls is False:
        return None
    if tls is True:
        return Tls()
    if isinstance(tls, Tls):
        return tls
    return Tls(ca_file=tls)


def _connect_timeout_from_environment() -> float:
    text = os.environ.get("TESSERA_CONNECT_TIMEOUT", "")
    if not text:
        return DEFAULT_CONNECT_TIMEOUT_S
    try:
        seconds = float(text)
    except ValueError:
        seconds = -1
    if not 0 <= seconds <= 86400:
        raise ValueError(
            f"TESSERA_CONNECT_TIMEOUT='{text}' is not a number of seconds in [0, 86400]"
        )
    return seconds


def _error(e: grpc.RpcError, context: str) -> FarmError:
    return FarmError(e.code(), e.details() or "", context)


def _read_bytes(path: Optional[PathLike]) -> Optional[bytes]:
    return Path(path).read_bytes() if path else None


class Client:
    """One connection to a coordinator.

    address: "host:port"; default $TESSERA_COORDINATOR, else 127.0.0.1:50051.
    token: the bearer token sent on every call; default the file `token_file` names,
        else $TESSERA_TOKEN, else the file $TESSERA_TOKEN_FILE names; none if unset.
    tls: None: TLS if $TESSERA_TLS_CA is set (with $TESSERA_TLS_CERT, _KEY,
        _SERVER_NAME), else plaintext; False: plaintext; True: TLS checked against the
        system's root certificates; a path: TLS with that CA file; or a Tls.
    connect_timeout: seconds a call keeps trying a coordinator that does not answer
        (starting, restarting) before failing with the reason it could not connect;
        default $TESSERA_CONNECT_TIMEOUT, else 30.
    call_timeout: seconds each unary call may take.

    Calls raise FarmError. Every call but SubmitJob (reads, cancels, uploads, downloads,
    watches) is tried again while the coordinator answers UNAVAILABLE, for at most
    connect_timeout; a submission is not, since one that reached the coordinator may
    have created the job. The client is usable from several threads; close() it (or use
    `with`) to free the channel.
    """

    def __init__(
        self,
        address: Optional[str] = None,
        token: Optional[str] = None,
        tls: Union[None, bool, PathLike, Tls] = None,
        *,
        token_file: Optional[PathLike] = None,
        connect_timeout: Optional[float] = None,
        call_timeout: float = CALL_TIMEOUT_S,
    ):
        self._address = address or os.environ.get("TESSERA_COORDINATOR") or DEFAULT_ADDRESS
        token = _resolve_token(token, token_file)
        self._metadata = (("authorization", "Bearer " + token),) if token else None
        self._connect_timeout = (
            _connect_timeout_from_environment() if connect_timeout is None else connect_timeout
        )
        self._call_timeout = call_timeout
        # gRPC's reconnect backoff grows to two minutes by default; a watch should find a
        # restarted coordinator within a second or two.
        options = [
            ("grpc.max_receive_message_length", 64 << 20),
            ("grpc.initial_reconnect_backoff_ms", 200),
            ("grpc.min_reconnect_backoff_ms", 200),
            ("grpc.max_reconnect_backoff_ms", 2000),
        ]
        self._tls = _resolve_tls(tls)
        if self._tls is None:
            self._channel = grpc.insecure_channel(self._address, options=options)
        else:
            t = self._tls
            if (t.cert_file is None) != (t.key_file is None):
                raise ValueError("a client certificate needs both cert_file and key_file")
            credentials = grpc.ssl_channel_credentials(
                root_certificates=_read_bytes(t.ca_file),
                private_key=_read_bytes(t.key_file),
                certificate_chain=_read_bytes(t.cert_file),
            )
            if t.server_name:
                options.append(("grpc.ssl_target_name_override", t.server_name))
            self._channel = grpc.secure_channel(self._address, credentials, options=options)
        self._farm = pb_grpc.FarmStub(self._channel)
        self._blobs = pb_grpc.BlobStoreStub(self._channel)

    @property
    def address(self) -> str:
        return self._address

    @property
    def tls(self) -> Optional[Tls]:
        return self._tls

    def close(self) -> None:
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"tessera.Client({self._address!r}, tls={self._tls is not None})"

    # -- jobs --------------------------------------------------------------------------

    def submit(
        self,
        scene_path: PathLike,
        *,
        frames: Union[None, int, str, Iterable[int]] = None,
        spp: Optional[int] = None,
        width: Optional[int] = None,
        height: Optional[int] = None,
        name: Optional[str] = None,
        priority: int = 0,
        **render_options: Any,
    ) -> str:
        """Uploads the scene's bundle (the scene file and every file it references,
        each content once, only what the coordinator lacks) and submits a job; returns
        its id ("job-12").

        frames: a frame number, a frame list ("1-9:2,20,30-32", as `--frames`) or
            numbers (range(0, 12)); default the frames the scene's "animation" names.
        spp, width, height and `render_options` (any other field of
            tessera.v1.RenderOptions: integrator, seed, max_depth, tile_size, sampler,
            photons_global, ...) replace the scene's "render" block; unset ones keep it.
        name: the output file stem, [A-Za-z0-9._-]+; default the scene file's stem, or
            its folder's name for "scene.json".
        priority: higher runs first.

        Raises ValueError or OSError for a scene that cannot be bundled, TypeError for an
        unknown render option, FarmError for a refused job (INVALID_ARGUMENT naming the
        scene's problem, RESOURCE_EXHAUSTED over a limit, ...)."""
        options = dict(render_options)
        for key, value in (("spp", spp), ("width", width), ("height", height)):
            if value is not None:
                options[key] = value
        known = pb.RenderOptions.DESCRIPTOR.fields_by_name
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise TypeError(
                f"unknown render option(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}"
            )
        files = _bundle.collect_bundle(scene_path)
        frame_list = (
            _bundle.scene_frames(_bundle.read_scene(scene_path))
            if frames is None
            else _bundle.frames_of(frames)
        )
        spec = pb.JobSpec(
            name=name or _bundle.default_job_name(scene_path),
            scene_path=files[0].path,
            options=pb.RenderOptions(**{k: v for k, v in options.items() if v is not None}),
            frame_start=frame_list[0],
            frame_end=frame_list[-1],
            priority=priority,
        )
        # A range travels as frame_start..frame_end alone, which every coordinator reads.
        if not _bundle.is_frame_range(frame_list):
            spec.frames.extend(frame_list)
        for f in files:
            spec.files.add(path=f.path, hash=f.sha256, size=f.size)
        self.upload(files)
        # Not repeated: a submission that reached the coordinator may have created the job.
        try:
            response = self._farm.SubmitJob(
                pb.SubmitJobRequest(spec=spec), timeout=SUBMIT_TIMEOUT_S, metadata=self._metadata
            )
        except grpc.RpcError as e:
            raise _error(e, "submission refused") from None
        return response.job_id

    def status(self, job_id: str) -> JobStatus:
        """The job now. NOT_FOUND for an unknown job, INVALID_ARGUMENT for a malformed id."""
        request = pb.GetJobRequest(job_id=job_id)
        m = self._retrying(lambda **kw: self._farm.GetJob(request, **kw), f"getting job '{job_id}'")
        return JobStatus.from_proto(m)

    def jobs(self) -> List[JobStatus]:
        """Every job the coordinator knows."""
        m = self._retrying(
            lambda **kw: self._farm.ListJobs(pb.ListJobsRequest(), **kw), "listing jobs"
        )
        return [JobStatus.from_proto(j) for j in m.jobs]

    def workers(self) -> List[WorkerStatus]:
        m = self._retrying(
            lambda **kw: self._farm.ListWorkers(pb.ListWorkersRequest(), **kw), "listing workers"
        )
        return [WorkerStatus.from_proto(w) for w in m.workers]

    def cancel(self, job_id: str) -> JobStatus:
        """Cancels the job (a finished job stays as it is); returns its status."""
        request = pb.CancelJobRequest(job_id=job_id)
        m = self._retrying(
            lambda **kw: self._farm.CancelJob(request, **kw), f"cancelling job '{job_id}'"
        )
        return JobStatus.from_proto(m.status)

    def set_priority(self, job_id: str, priority: int) -> JobStatus:
        """Changes a queued or running job's priority (higher runs first).
        FAILED_PRECONDITION for a finished job; INVALID_ARGUMENT over the token's
        max_priority."""
        request = pb.SetJobPriorityRequest(job_id=job_id, priority=priority)
        m = self._retrying(
            lambda **kw: self._farm.SetJobPriority(request, **kw),
            f"setting the priority of job '{job_id}'",
        )
        return JobStatus.from_proto(m)

    def retry(self, job_id: str) -> JobStatus:
        """Runs a failed or cancelled job again: its unwritten frames are queued, tasks
        done keep their results. FAILED_PRECONDITION for a done or unfinished job."""
        request = pb.RetryJobRequest(job_id=job_id)
        m = self._retrying(
            lambda **kw: self._farm.RetryJob(request, **kw), f"retrying job '{job_id}'"
        )
        return JobStatus.from_proto(m)

    def delete(self, job_id: str) -> Any:
        """Deletes the job (cancelled first if it runs), its records and the blobs no
        other job needs; frames already written stay. Returns the coordinator's
        tessera.v1.DeleteJobResponse (blobs_removed, bytes_removed, blobs_left_for_gc)."""
        request = pb.DeleteJobRequest(job_id=job_id)
        # Not repeated: a deletion that reached the coordinator would then be NOT_FOUND.
        try:
            return self._farm.DeleteJob(
                request, timeout=self._call_timeout, metadata=self._metadata
            )
        except grpc.RpcError as e:
            raise _error(e, f"deleting job '{job_id}'") from None

    def log(self, job_id: str, *, task: Optional[int] = None, limit: int = 0) -> List[JobLogEntry]:
        """The job's log, oldest first: its last `limit` entries (0: up to 1000), of one
        task (its number in the job) if `task` is given."""
        request = pb.GetJobLogRequest(job_id=job_id, limit=limit)
        if task is not None:
            request.task = task
        m = self._retrying(
            lambda **kw: self._farm.GetJobLog(request, **kw), f"reading the log of job '{job_id}'"
        )
        return [JobLogEntry.from_proto(e) for e in m.entries]

    def set_worker_enabled(self, worker: str, enabled: bool) -> WorkerStatus:
        """Disables a worker (it finishes what it holds, then takes no tasks) or enables
        it again; by name or worker id. NOT_FOUND for an unknown worker."""
        request = pb.SetWorkerEnabledRequest(worker=worker, enabled=enabled)
        m = self._retrying(
            lambda **kw: self._farm.SetWorkerEnabled(request, **kw),
            f"{'enabling' if enabled else 'disabling'} worker '{worker}'",
        )
        return WorkerStatus.from_proto(m)

    def watch(
        self, job_id: str, *, timeout: Optional[float] = None, reconnect_seconds: float = 30.0
    ) -> Iterator[JobEvent]:
        """Yields the job's events until it is DONE, FAILED or CANCELLED (that event is
        the last). The first is a snapshot of the job as it is; a finished job yields
        one event. If the coordinator goes away meanwhile (a restart), the watch reopens
        for up to `reconnect_seconds`, starting again with a snapshot.

        timeout: seconds for the whole watch; then FarmError DEADLINE_EXCEEDED.
        Leaving the loop early (break) closes the stream."""
        deadline = None if timeout is None else time.monotonic() + timeout
        request = pb.WatchJobRequest(job_id=job_id)
        last: Optional[JobStatus] = None
        # Before the first event: a coordinator not reachable yet; after: one that left.
        retry = _Retry(self._connect_timeout)
        while True:
            remaining = None if deadline is None else max(deadline - time.monotonic(), 0.001)
            call = self._farm.WatchJob(request, timeout=remaining, metadata=self._metadata)
            error: Optional[grpc.RpcError] = None
            try:
                for message in call:
                    event = JobEvent(JobStatus.from_proto(message.status), message.message)
                    last = event.status
                    retry = _Retry(reconnect_seconds)
                    yield event
            except grpc.RpcError as e:
                error = e
            finally:
                call.cancel()  # a no-op once the stream ended; closes it after a break
            if last is not None and last.finished:
                return
            if deadline is not None and time.monotonic() >= deadline:
                raise FarmError(
                    grpc.StatusCode.DEADLINE_EXCEEDED,
                    f"job {job_id} did not finish within {timeout} s"
                    + (f" (last seen {last.state.value})" if last else ""),
                    f"watching job {job_id}",
                )
            # The stream broke (or ended early) with the job unfinished: the coordinator
            # went away. Try again for a while; it may be restarting.
            if (error is None or error.code() == grpc.StatusCode.UNAVAILABLE) and retry.again(
                deadline
            ):
                continue
            if error is None:
                raise FarmError(
                    grpc.StatusCode.UNAVAILABLE,
                    "the stream ended before the job did",
                    f"watching job {job_id}",
                )
            raise _error(error, f"watching job {job_id}") from None

    def wait(self, job_id: str, *, timeout: Optional[float] = None) -> JobStatus:
        """Follows the job to its end (see watch) and returns its final status, whether
        DONE, FAILED (status.error says why) or CANCELLED."""
        last: Optional[JobStatus] = None
        for event in self.watch(job_id, timeout=timeout):
            last = event.status
        assert last is not None  # watch ends only after a finished job's event
        return last

    # -- frames ------------------------------------------------------------------------

    def fetch(
        self,
        job_id: str,
        out_dir: PathLike,
        *,
        frames: Union[None, int, str, Iterable[int]] = None,
        preview: bool = False,
    ) -> List[Path]:
        """Downloads the job's finished frames into out_dir (created if needed) as
        <name>.<frame:04>.exr, and <name>.<frame:04>.png previews if `preview`; returns
        the paths written. `frames` picks some (default every finished one); asking for
        a frame that is not done is NOT_FOUND. FAILED_PRECONDITION when no frame is done
        yet. Each file is checked against the coordinator's SHA-256 and appears
        atomically."""
        job = self.status(job_id)
        done = [f.frame for f in job.frames if f.state == FrameState.DONE]
        if frames is None:
            if not done:
                raise FarmError(
                    grpc.StatusCode.FAILED_PRECONDITION,
                    f"job {job_id} ({job.state.value}) has no finished frame to fetch yet",
                    f"fetching job {job_id}",
                )
            wanted = done
        else:
            wanted = _bundle.frames_of(frames)
        folder = Path(out_dir)
        folder.mkdir(parents=True, exist_ok=True)
        written: List[Path] = []
        for frame in wanted:
            stem = f"{job.name}.{frame:04d}"
            written.append(self.download_frame(job_id, frame, folder / f"{stem}.exr"))
            if preview:
                written.append(
                    self.download_frame(job_id, frame, folder / f"{stem}.png", preview=True)
                )
        return written

    def download_frame(
        self, job_id: str, frame: int, path: PathLike, *, preview: bool = False
    ) -> Path:
        """Streams one finished frame's EXR (or its PNG preview) into `path`, atomically
        (a temporary file beside it, then a rename), and checks it against the SHA-256
        the coordinator sends: DATA_LOSS, and `path` untouched, if it arrived damaged.
        NOT_FOUND until the frame is done."""
        target = Path(path)
        temp = target.parent / f".{target.name}.tmp-{os.getpid()}-{next(_temp_counter)}"
        what = f"frame {frame} of job {job_id}"
        request = pb.DownloadFrameRequest(job_id=job_id, frame=frame, preview=preview)
        try:
            with open(temp, "xb") as out:
                got, expected = self._retrying(
                    lambda **kw: self._download(request, out, **kw),
                    f"downloading {what}",
                    timeout=None,
                )
                if expected and expected != got:
                    raise FarmError(
                        grpc.StatusCode.DATA_LOSS,
                        f"{what} arrived damaged (SHA-256 {got}, the coordinator's file has "
                        f"{expected}); {target} was not written: fetch it again",
                        f"downloading {what}",
                    )
                out.flush()
                os.fsync(out.fileno())
            os.replace(temp, target)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temp)
            raise
        return target

    def _download(self, request: Any, out: BinaryIO, **call_options: Any) -> Tuple[str, str]:
        """One try of DownloadFrame into `out` (from its start): the SHA-256 of what came,
        and the one the coordinator sent after it ("" if none)."""
        out.seek(0)
        out.truncate()
        digest = hashlib.sha256()
        call = self._farm.DownloadFrame(request, **call_options)
        try:
            for chunk in call:
                digest.update(chunk.data)
                out.write(chunk.data)
        except BaseException:
            call.cancel()
            raise
        expected = dict(call.trailing_metadata() or ()).get(_FRAME_SHA256_KEY, "")
        return digest.hexdigest(), expected

    # -- blobs -------------------------------------------------------------------------

    def upload(self, files: Iterable[_bundle.BundleFile]) -> int:
        """Uploads the files the coordinator's store lacks, each content once; returns
        how many were sent. submit() calls it; it is public for tools that build their
        own specs."""
        files = list(files)
        if not files:
            return 0
        request = pb.FindMissingBlobsRequest(hashes=[f.sha256 for f in files])
        missing = set(
            self._retrying(
                lambda **kw: self._blobs.FindMissingBlobs(request, **kw), "checking the blob store"
            ).missing
        )
        sent = 0
        for f in files:
            if f.sha256 not in missing:
                continue
            missing.discard(f.sha256)  # two paths with the same content are one blob
            # Repeated like a read: the store keeps one copy of any content.
            response = self._retrying(
                lambda **kw: self._blobs.PutBlob(_blob_messages(f), **kw),
                f"uploading {f.local_path}",
                timeout=None,
            )
            if response.hash != f.sha256:
                raise FarmError(
                    grpc.StatusCode.DATA_LOSS,
                    f"{f.local_path} changed while it was being submitted",
                    f"uploading {f.local_path}",
                )
            sent += 1
        return sent

    # -- calls -------------------------------------------------------------------------

    def _retrying(self, call: Callable[..., T], context: str, timeout: Any = _CALL_TIMEOUT) -> T:
        """Makes a call that may safely be repeated, again with backoff while the
        coordinator answers UNAVAILABLE (not reachable yet, restarting, overloaded), for
        at most connect_timeout; then raises the last error, which says why (connection
        refused, a TLS failure). Calls fail fast rather than wait for a connection, so
        that a coordinator that is down is reported as such, not as "deadline exceeded".
        timeout: the call's, default call_timeout; None: none (streams of any length)."""
        retry = _Retry(self._connect_timeout)
        while True:
            try:
                return call(
                    timeout=self._call_timeout if timeout is _CALL_TIMEOUT else timeout,
                    metadata=self._metadata,
                )
            except grpc.RpcError as e:
                if e.code() != grpc.StatusCode.UNAVAILABLE or not retry.again():
                    raise _error(e, context) from None


class _Retry:
    """The pauses between tries of a call: 0.1 s, doubling up to 2 s, for at most
    `window` seconds after the first failure."""

    def __init__(self, window: float):
        self._window = window
        self._until: Optional[float] = None
        self._pause = 0.1

    def again(self, deadline: Optional[float] = None) -> bool:
        """Pauses and returns True if there is time for another try (before `deadline`
        too, a time.monotonic() value); False at once if not."""
        now = time.monotonic()
        if self._until is None:
            self._until = now + self._window
        end = self._until if deadline is None else min(self._until, deadline)
        if now + self._pause >= end:
            return False
        time.sleep(self._pause)
        self._pause = min(self._pause * 2, 2.0)
        return True


_temp_counter = itertools.count()


def _blob_messages(f: _bundle.BundleFile) -> Iterator[Any]:
    """PutBlob's stream: the header, then the file in chunks of at most 1 MiB."""
    yield pb.PutBlobRequest(header=pb.BlobHeader(hash=f.sha256, size=f.size))
    with open(f.local_path, "rb") as data:
        for chunk in iter(lambda: data.read(_CHUNK_BYTES), b""):
            yield pb.PutBlobRequest(data=chunk)
