"""Tessera's Python client: submit scenes to a render farm, watch them, fetch the frames.

    import tessera

    with tessera.Client("127.0.0.1:50051") as farm:
        job = farm.submit("scenes/cornell-box/scene.json", spp=64, width=256, height=256)
        for event in farm.watch(job):
            print(f"{event.state.value} {event.progress:.0%} {event.message}")
        farm.fetch(job, "out/")

See python/README.md. The generated gRPC stubs are tessera.v1.tessera_pb2 and
tessera.v1.tessera_pb2_grpc, for calls this module does not wrap.
"""

from .bundle import BundleFile, collect_bundle, parse_frame_list
from .client import (
    DEFAULT_ADDRESS,
    Client,
    FarmError,
    FrameState,
    FrameStatus,
    JobEvent,
    JobLogEntry,
    JobState,
    JobStatus,
    TaskFailure,
    Tls,
    WorkerStatus,
)

__all__ = [
    "BundleFile",
    "Client",
    "DEFAULT_ADDRESS",
    "FarmError",
    "FrameState",
    "FrameStatus",
    "JobEvent",
    "JobLogEntry",
    "JobState",
    "JobStatus",
    "TaskFailure",
    "Tls",
    "WorkerStatus",
    "collect_bundle",
    "parse_frame_list",
]
