#!/usr/bin/python3
"""The Python client (python/tessera) against a real farm on 127.0.0.1.

ctest runs it (tests/CMakeLists.txt) with PYTHONPATH=build/python and the built binaries:

    python_client_test.py --tessera build/cli/tessera
        --coordinator build/coordinator/tessera-coordinator
        --worker build/worker/tessera-worker --source-dir .  [unittest arguments]

Each test has its own temporary folder and processes (a coordinator on port 0, read back
from --port-file; workers), each in a session of its own, killed in all cases when the
test ends (and by the kernel if this process dies: setpriv --pdeathsig). Every wait has
a deadline. Set TESSERA_KEEP_TEST_DIRS=1 to keep the folders; a failing test prints its
processes' logs.

Pixels are compared with OpenImageIO's oiiotool (package openimageio-tools): the SHA-1
of the pixel data of every channel, which the system Python cannot read from an EXR.
"""

import argparse
import contextlib
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path

# Beside this file: Python puts the folder of the script it runs first on sys.path.
from farm_processes import FarmProcesses, farm_argument_parser, wait_for

try:
    import grpc

    import tessera
except ImportError as e:
    sys.exit(
        f"python_client_test: cannot import the client ({e}); run it with Debian's "
        "/usr/bin/python3 (python3-grpcio, python3-protobuf) and PYTHONPATH=build/python "
        "after building the tessera_python target"
    )

ARGS = argparse.Namespace()
START_DEADLINE_S = 60
JOB_DEADLINE_S = 240
CLI_DEADLINE_S = 180

# The client reads these; the tests say explicitly what they want.
for _name in (
    "TESSERA_COORDINATOR",
    "TESSERA_TOKEN",
    "TESSERA_TOKEN_FILE",
    "TESSERA_TLS_CA",
    "TESSERA_TLS_CERT",
    "TESSERA_TLS_KEY",
    "TESSERA_TLS_SERVER_NAME",
    "TESSERA_CONNECT_TIMEOUT",
):
    os.environ.pop(_name, None)


class Farm(FarmProcesses):
    """A test's folder and the processes it started."""

    def __init__(self, name):
        super().__init__(f"tessera_pyclient_{name}_", ARGS.tessera, CLI_DEADLINE_S)

    def start_coordinator(self, name="coordinator", extra=()):
        """Starts a coordinator on 127.0.0.1, any free port; returns the port once it
        serves."""
        port_file = self.dir / f"{name}.port"
        p = self.start(
            [
                ARGS.coordinator,
                "--listen", "127.0.0.1:0",
                "--port-file", port_file,
                "--state", self.dir / f"{name}-state",
                "--output", self.dir / f"{name}-frames",
                *extra,
            ],
            name,
        )
        deadline = time.monotonic() + START_DEADLINE_S
        while time.monotonic() < deadline:
            text = port_file.read_text() if port_file.exists() else ""
            if text.strip().isdigit() and int(text) > 0 and port_file.read_text() == text:
                return int(text)
            if p.poll() is not None:
                break
            time.sleep(0.01)
        raise AssertionError(f"the coordinator did not write {port_file}:\n{self.log_tails()}")

    def start_worker(self, port, name, extra=()):
        return self.start(
            [
                ARGS.worker,
                "--coordinator", f"127.0.0.1:{port}",
                "--threads", "2",
                "--name", name,
                "--cache", self.dir / f"cache-{name}",
                *extra,
            ],
            name,
        )


@contextlib.contextmanager
def farm_of(test_name):
    """A Farm whose processes are killed however the block ends; its folder is removed
    after a success, kept (and its logs printed) after a failure."""
    farm = Farm(test_name)
    ok = False
    try:
        yield farm
        ok = True
    finally:
        farm.finish(ok)


def image_fingerprint(path):
    """(resolution line, channel list, SHA-1 of the pixel data) as oiiotool reports them;
    the header's other attributes (render time, date) may differ between equal images."""
    r = subprocess.run(
        ["oiiotool", "-v", "--info", "--hash", str(path)],
        capture_output=True, text=True, timeout=120,
    )
    if r.returncode != 0:
        raise AssertionError(f"oiiotool cannot read {path}:\n{r.stdout}{r.stderr}")
    size = re.search(r":\s+(\d+)\s+x\s+(\d+),\s+\d+ channel", r.stdout)
    channels = re.search(r"channel list: (.*)", r.stdout)
    sha1 = re.search(r"SHA-1: ([0-9A-Fa-f]{40})", r.stdout)
    if not (size and channels and sha1):
        raise AssertionError(f"unexpected oiiotool output for {path}:\n{r.stdout}")
    return f"{size.group(1)}x{size.group(2)}", channels.group(1).strip(), sha1.group(1).upper()


class BundleTest(unittest.TestCase):
    """What submit() sends, without a farm."""

    def test_frame_lists_follow_the_cli_syntax(self):
        self.assertEqual(
            tessera.parse_frame_list("1-9:2,20,30-32,3"), [1, 3, 5, 7, 9, 20, 30, 31, 32]
        )
        self.assertEqual(tessera.parse_frame_list("7"), [7])
        for bad in ("", "1-", "-3", "5-2", "1:2", "1-9:0", "a", "1,,2", "10000001"):
            with self.subTest(text=bad), self.assertRaises(ValueError):
                tessera.parse_frame_list(bad)

    def test_bundle_holds_the_scene_and_every_referenced_file_once(self):
        with tempfile.TemporaryDirectory(prefix="tessera_pyclient_bundle_") as d:
            root = Path(d)
            (root / "meshes").mkdir()
            for name in ("a.obj", "b.obj", "meshes/c.obj", "sky.exr", "same.obj"):
                (root / name).write_bytes(b"content of " + name.encode())
            (root / "same.obj").write_bytes(b"content of a.obj")
            scene = root / "shot.json"
            scene.write_text(
                """{
                  // comments are allowed, as by the engine's reader
                  "camera": {"type": "perspective", "eye": [0, 0, 1], "target": [0, 0, 0]},
                  "shapes": [
                    {"type": "mesh", "file": "a.obj", "name": "/* not a comment */"},
                    {"type": "mesh", "file": "./a.obj"},
                    {"type": "mesh", "file": "same.obj"},
                    {"type": "mesh", "deform": {"keys": [{"time": 0, "file": "meshes/c.obj"},
                                                         {"time": 1, "file": "b.obj"}]}}
                  ],
                  /* block
                     comment */
                  "lights": [{"type": "environment", "file": "sky.exr"}]
                }"""
            )
            files = tessera.collect_bundle(scene)
            self.assertEqual(
                [f.path for f in files],
                ["shot.json", "a.obj", "same.obj", "meshes/c.obj", "b.obj", "sky.exr"],
            )
            a = next(f for f in files if f.path == "a.obj")
            same = next(f for f in files if f.path == "same.obj")
            self.assertEqual(a.sha256, same.sha256)
            self.assertEqual(a.size, len(b"content of a.obj"))

            for ref, why in (("../x.obj", "'..'"), ("/etc/passwd", "outside")):
                scene.write_text(json_scene_with_file(ref))
                with self.subTest(ref=ref), self.assertRaisesRegex(ValueError, why):
                    tessera.collect_bundle(scene)
            scene.write_text(json_scene_with_file("missing.obj"))
            with self.assertRaises(FileNotFoundError):
                tessera.collect_bundle(scene)


def json_scene_with_file(ref):
    return '{"camera": {}, "shapes": [{"type": "mesh", "file": "%s"}]}' % ref


class FarmTest(unittest.TestCase):
    def assertFarmError(self, code, call, *args, **kwargs):
        with self.assertRaises(tessera.FarmError) as caught:
            call(*args, **kwargs)
        self.assertEqual(caught.exception.code, code, str(caught.exception))
        self.assertTrue(str(caught.exception), "the error says what happened")
        return caught.exception

    def test_submit_watch_fetch_equals_a_local_render(self):
        scene = Path(ARGS.source_dir) / "scenes/cornell-box/scene.json"
        settings = dict(spp=4, width=32, height=32, tile_size=16)
        with farm_of("render") as farm:
            port = farm.start_coordinator()
            with tessera.Client(f"127.0.0.1:{port}") as client:
                job = client.submit(scene, frames=0, name="pycornell", **settings)
                self.assertRegex(job, r"^job-\d+$")
                # No worker yet: the first event is the queued job, and the ones after it
                # are the work done once a worker joins.
                events = client.watch(job, timeout=JOB_DEADLINE_S)
                first = next(events)
                self.assertEqual(first.status.job_id, job)
                self.assertEqual(first.state, tessera.JobState.QUEUED)
                self.assertEqual(first.status.tasks_done, 0)

                # A scene with meshes: the coordinator loads it at submission, so a file
                # missing from the bundle would be refused. Cancelled before it renders.
                veach = Path(ARGS.source_dir) / "scenes/veach-mis/scene.json"
                other = client.submit(veach, frames="0", spp=1, width=8, height=8, priority=-1)
                self.assertEqual(
                    sorted(f.path for f in tessera.collect_bundle(veach)),
                    ["plate1.obj", "plate2.obj", "plate3.obj", "plate4.obj", "scene.json"],
                )
                self.assertEqual(client.cancel(other).state, tessera.JobState.CANCELLED)
                self.assertEqual(client.wait(other, timeout=30).state, "CANCELLED")
                self.assertFarmError(
                    grpc.StatusCode.FAILED_PRECONDITION, client.fetch, other, farm.dir
                )
                self.assertEqual({j.job_id for j in client.jobs()}, {job, other})

                farm.start_worker(port, "w1")
                seen = [first] + list(events)
                final = seen[-1].status
                self.assertEqual(final.state, tessera.JobState.DONE, final.error)
                self.assertGreaterEqual(len(seen), 2)
                self.assertTrue(all(not e.status.finished for e in seen[:-1]))
                progress = [e.progress for e in seen]
                self.assertEqual(progress, sorted(progress), "progress never goes back")
                self.assertEqual(final.tasks_done, final.tasks_total)
                self.assertEqual(final.progress, 1.0)

                status = client.status(job)
                self.assertEqual(status.state, tessera.JobState.DONE)
                self.assertEqual((status.width, status.height, status.spp), (32, 32, 4))
                self.assertEqual(status.name, "pycornell")
                self.assertEqual(status.frames_done, 1)
                self.assertEqual(status.frames[0].frame, 0)
                self.assertIsNotNone(status.finished_at)
                self.assertIn("w1", [w.name for w in client.workers()])

                fetched = client.fetch(job, farm.dir / "fetched", preview=True)
                exr = farm.dir / "fetched" / "pycornell.0000.exr"
                self.assertEqual(fetched, [exr, farm.dir / "fetched" / "pycornell.0000.png"])
                self.assertEqual(
                    sorted(os.listdir(farm.dir / "fetched")),
                    ["pycornell.0000.exr", "pycornell.0000.png"],
                    "no temporary file is left",
                )

            local = farm.dir / "local.exr"
            farm.cli(
                "render", scene, "-q", "-o", local, "--frame", "0",
                "--spp", "4", "--width", "32", "--height", "32", "--tile-size", "16",
            )
            local_print, farm_print = image_fingerprint(local), image_fingerprint(exr)
            self.assertEqual(local_print[0], "32x32")
            self.assertEqual(
                farm_print, local_print, "the farm's frame equals a local render bit for bit"
            )

    def test_steering_jobs_and_workers(self):
        scene = Path(ARGS.source_dir) / "scenes/cornell-box/scene.json"
        with farm_of("steering") as farm:
            port = farm.start_coordinator()
            farm.start_worker(port, "w1")
            with tessera.Client(f"127.0.0.1:{port}") as client:
                wait_for("w1 to register", lambda: [w.name for w in client.workers()] == ["w1"])
                disabled = client.set_worker_enabled("w1", False)
                self.assertTrue(disabled.disabled)
                self.assertIn(disabled.state, ("disabled", "draining"))
                job = client.submit(scene, frames=0, spp=2, width=32, height=32, tile_size=16)
                self.assertEqual(client.set_priority(job, 5).priority, 5)
                self.assertEqual(client.cancel(job).state, tessera.JobState.CANCELLED)
                self.assertEqual(client.retry(job).state, tessera.JobState.QUEUED)
                self.assertFarmError(grpc.StatusCode.FAILED_PRECONDITION, client.retry, job)
                client.set_worker_enabled("w1", True)
                self.assertEqual(client.wait(job, timeout=JOB_DEADLINE_S).state, "DONE")
                kinds = [e.kind for e in client.log(job)]
                for kind in ("submitted", "priority", "cancelled", "retried", "done", "frame",
                             "job-done"):
                    self.assertIn(kind, kinds)
                task0 = client.log(job, task=0)
                self.assertEqual([e.kind for e in task0], ["done"])
                self.assertEqual(task0[0].worker, "w1")
                self.assertIsNotNone(task0[0].at)
                self.assertGreaterEqual(task0[0].at_unix_ms, task0[0].leased_unix_ms)
                self.assertGreater(task0[0].leased_unix_ms, 0)
                wait_for("w1 to report its samples",
                         lambda: client.workers()[0].samples_done >= 32 * 32 * 2)
                self.assertGreater(client.workers()[0].rays_traced, 0)
                deleted = client.delete(job)
                self.assertGreater(deleted.blobs_removed, 0)
                self.assertFarmError(grpc.StatusCode.NOT_FOUND, client.status, job)
                self.assertFarmError(grpc.StatusCode.NOT_FOUND, client.set_worker_enabled,
                                     "nobody", False)

    def test_errors_carry_the_status_code(self):
        with farm_of("errors") as farm:
            port = farm.start_coordinator()
            os.environ["TESSERA_COORDINATOR"] = f"127.0.0.1:{port}"
            try:
                client = tessera.Client()  # the address from the environment
            finally:
                del os.environ["TESSERA_COORDINATOR"]
            with client:
                self.assertEqual(client.address, f"127.0.0.1:{port}")
                e = self.assertFarmError(grpc.StatusCode.NOT_FOUND, client.status, "job-999999")
                self.assertIn("job-999999", e.details)
                self.assertTrue(str(e).startswith("getting job 'job-999999': NOT_FOUND: "), str(e))
                self.assertFarmError(grpc.StatusCode.NOT_FOUND, client.cancel, "job-999999")
                self.assertFarmError(
                    grpc.StatusCode.NOT_FOUND, client.fetch, "job-999999", farm.dir
                )
                self.assertFarmError(
                    grpc.StatusCode.NOT_FOUND, lambda: list(client.watch("job-999999", timeout=30))
                )
                self.assertFarmError(grpc.StatusCode.INVALID_ARGUMENT, client.status, "not-a-job")
                scene = Path(ARGS.source_dir) / "scenes/cornell-box/scene.json"
                with self.assertRaisesRegex(TypeError, "unknown render option"):
                    client.submit(scene, spp=1, sppp=2)
                # Refused by the coordinator's limits (default --max-spp 65536).
                self.assertFarmError(
                    grpc.StatusCode.RESOURCE_EXHAUSTED, client.submit, scene, spp=1 << 20
                )
                self.assertEqual(client.jobs(), [])

            farm.stop()  # nothing listens there now
            with tessera.Client(f"127.0.0.1:{port}", connect_timeout=0.5) as gone:
                self.assertFarmError(grpc.StatusCode.UNAVAILABLE, gone.status, "job-1")

    def test_tls_and_token(self):
        with farm_of("tls") as farm:
            pki, tokens = farm.dir / "pki", farm.dir / "tokens"
            farm.cli("cert", "ca", "--dir", pki)
            farm.cli("cert", "server", "--dir", pki, "--host", "localhost")
            token_file = farm.dir / "client.token"
            farm.cli(
                "token", "--role", "client", "--name", "py", "--tokens", tokens,
                "--out", token_file,
            )
            port = farm.start_coordinator(
                extra=["--tls-cert", pki / "server.pem", "--tls-key", pki / "server.key",
                       "--tokens", tokens]
            )
            address = f"127.0.0.1:{port}"
            token = token_file.read_text().strip()
            ca = pki / "ca.pem"

            with tessera.Client(address, token=token, tls=ca) as client:
                self.assertFarmError(grpc.StatusCode.NOT_FOUND, client.status, "job-1")
                self.assertEqual(client.jobs(), [])
            # The token from $TESSERA_TOKEN_FILE, TLS from $TESSERA_TLS_CA, as the CLI reads them.
            os.environ.update(TESSERA_TOKEN_FILE=str(token_file), TESSERA_TLS_CA=str(ca))
            try:
                with tessera.Client(address) as client:
                    self.assertIsNotNone(client.tls)
                    self.assertEqual(client.jobs(), [])
            finally:
                del os.environ["TESSERA_TOKEN_FILE"], os.environ["TESSERA_TLS_CA"]
            with tessera.Client(address, tls=tessera.Tls(ca_file=ca)) as anonymous:
                self.assertFarmError(grpc.StatusCode.UNAUTHENTICATED, anonymous.jobs)
            with tessera.Client(address, token="not-a-valid-token-at-all", tls=ca) as wrong:
                self.assertFarmError(grpc.StatusCode.UNAUTHENTICATED, wrong.jobs)
            with tessera.Client(address, token=token, connect_timeout=1) as plaintext:
                self.assertFarmError(grpc.StatusCode.UNAVAILABLE, plaintext.jobs)


def main():
    parser = farm_argument_parser(__doc__.splitlines()[0])
    args, rest = parser.parse_known_args()
    vars(ARGS).update(vars(args))
    # ctest stops a test that runs too long with SIGTERM: clean up as after a failure.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit("python_client_test: terminated"))
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
