#!/usr/bin/python3
"""The coordinator's web dashboard in a real browser, against a real farm on 127.0.0.1.

ctest runs it (tests/CMakeLists.txt) with the built binaries:

    dashboard_browser_test.py --tessera build/cli/tessera
        --coordinator build/coordinator/tessera-coordinator
        --worker build/worker/tessera-worker --source-dir .  [unittest arguments]

A coordinator (--http-listen 127.0.0.1:0, the port read back from --http-port-file) and a
worker render a job that the `tessera submit` command sent, big enough to take a while on
two threads. Debian's Chromium, headless, driven by Selenium through chromedriver (packages
chromium, chromium-driver, python3-selenium), loads the page and must see the job's row
appear and its progress advance, the live preview of the frame load while the frame renders
(an image the coordinator made from the tiles done so far, not the written frame), the
worker's row, then set the job's priority, cancel the job with its button and see it
CANCELLED (on the page and through the JSON API), and disable the worker.

Processes run in sessions of their own and are killed however the test ends (and by the
kernel if this process dies: setpriv --pdeathsig). Every wait has a deadline; none is a
measurement. Set TESSERA_KEEP_TEST_DIRS=1 to keep the folder; a failure prints the logs.
"""

import argparse
import contextlib
import json
import os
import signal
import sys
import unittest
import urllib.request
from pathlib import Path

# Beside this file: Python puts the folder of the script it runs first on sys.path.
import farm_processes
from farm_processes import FarmProcesses, farm_argument_parser

try:
    from selenium import webdriver
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
except ImportError as e:
    sys.exit(
        f"dashboard_browser_test: cannot import selenium ({e}); run it with Debian's "
        "/usr/bin/python3 with python3-selenium installed (deploy/setup.sh)"
    )

ARGS = argparse.Namespace()
START_DEADLINE_S = 60
STEP_DEADLINE_S = 90
CLI_DEADLINE_S = 120

# The job: 256 tiles of 16x16 pixels at 256 samples each, 4 frames: minutes of work on two
# threads, so that it is still rendering while the page is watched, and then cancelled.
JOB_ARGS = ["--spp", "256", "--width", "256", "--height", "256", "--tile-size", "16",
            "--frames", "0-3", "--name", "browser"]


def wait_for(what, condition, deadline_s=STEP_DEADLINE_S, interval_s=0.1, on_timeout=None):
    """farm_processes.wait_for, where an element replaced while being read is "not yet"."""
    return farm_processes.wait_for(what, condition, deadline_s, interval_s, on_timeout,
                                   retry_on=(WebDriverException,))


class Farm(FarmProcesses):
    """The test's folder and the processes it started."""

    def __init__(self):
        super().__init__("tessera_dashboard_", ARGS.tessera, CLI_DEADLINE_S)

    def read_port(self, path, process):
        def port():
            if process.poll() is not None:
                raise AssertionError(f"{process.args} exited:\n{self.log_tails()}")
            text = path.read_text() if path.exists() else ""
            return int(text) if text.strip().isdigit() and int(text) > 0 else None

        return wait_for(f"{path}", port, START_DEADLINE_S, 0.02, self.log_tails)

    def start_coordinator(self):
        """Returns (gRPC port, dashboard port) once both serve."""
        grpc_file, http_file = self.dir / "grpc.port", self.dir / "http.port"
        p = self.start(
            [
                ARGS.coordinator,
                "--listen", "127.0.0.1:0", "--port-file", grpc_file,
                "--http-listen", "127.0.0.1:0", "--http-port-file", http_file,
                "--state", self.dir / "state", "--output", self.dir / "frames",
            ],
            "coordinator",
        )
        # The gRPC port file is written last: once it is there, both ports serve.
        grpc_port = self.read_port(grpc_file, p)
        return grpc_port, self.read_port(http_file, p)


def start_browser(profile_dir):
    """Headless Chromium under chromedriver. --no-sandbox: Chromium refuses to run as root
    (CI) with its sandbox; the pages it loads here are our own."""
    options = Options()
    options.binary_location = ARGS.chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--disable-extensions", "--no-first-run", "--window-size=1400,1200",
                f"--user-data-dir={profile_dir}"):
        options.add_argument(arg)
    service = Service(executable_path=ARGS.chromedriver,
                      log_path=str(Path(profile_dir).parent / "chromedriver.log"))
    driver = webdriver.Chrome(service=service, options=options)
    driver.set_page_load_timeout(STEP_DEADLINE_S)
    driver.set_script_timeout(STEP_DEADLINE_S)
    return driver


def get_json(url):
    with urllib.request.urlopen(url, timeout=30) as response:
        return json.loads(response.read())


class DashboardTest(unittest.TestCase):
    def test_follow_preview_and_cancel_a_job_in_the_browser(self):
        farm = Farm()
        driver = None
        ok = False
        try:
            grpc_port, http_port = farm.start_coordinator()
            base = f"http://127.0.0.1:{http_port}"
            job = farm.cli("submit", "--coordinator", f"127.0.0.1:{grpc_port}",
                           Path(ARGS.source_dir) / "scenes/cornell-box/scene.json",
                           *JOB_ARGS).strip()
            self.assertRegex(job, r"^job-\d+$")
            farm.start(
                [ARGS.worker, "--coordinator", f"127.0.0.1:{grpc_port}", "--threads", "2",
                 "--name", "w1", "--cache", farm.dir / "cache"],
                "worker",
            )
            driver = start_browser(farm.dir / "chromium-profile")
            driver.get(base + "/")
            self.assertEqual(driver.title, "Tessera farm")
            logs = farm.log_tails

            def job_row():
                return driver.find_element(By.CSS_SELECTOR, f'#jobs tr[data-job="{job}"]')

            def row_text(selector):
                return job_row().find_element(By.CSS_SELECTOR, selector).text

            def tasks_done():
                return int(job_row().find_element(By.CSS_SELECTOR, ".progress")
                           .get_attribute("data-done") or 0)

            # The job's row, then its progress bar moving while the worker renders.
            wait_for("the job's row", job_row, on_timeout=logs)
            self.assertEqual(row_text(".name"), "browser")
            wait_for("the job to run", lambda: row_text(".state") == "RUNNING", on_timeout=logs)
            first = wait_for("a first task done", tasks_done, on_timeout=logs)
            wait_for("the progress to advance", lambda: tasks_done() > first, on_timeout=logs)
            self.assertIn("%", row_text(".progress"))
            self.assertEqual(row_text(".stage"), "render")
            wait_for("the worker's row", lambda: driver.find_elements(
                By.CSS_SELECTOR, '#workers tr[data-worker="w1"]'), on_timeout=logs)

            # The running job is shown with the live preview of its frame.
            wait_for("the job's details", lambda: driver.find_element(
                By.ID, "detail-id").text == job, on_timeout=logs)
            preview = driver.find_element(By.CSS_SELECTOR, "img#preview")

            def live_preview():
                frame = driver.find_element(By.CSS_SELECTOR, '#frames tr[data-frame="0"] .state')
                if frame.text != "RENDERING":
                    return None
                width = driver.execute_script(
                    "const i = arguments[0]; return i.complete ? i.naturalWidth : 0;", preview)
                return (width, preview.get_attribute("src")) if width else None

            width, src = wait_for("the preview to load while frame 0 renders", live_preview,
                                  on_timeout=logs)
            self.assertEqual(width, 256)
            self.assertIn(f"/api/jobs/{job}/frames/0/preview.png", src)
            # What the page shows is the coordinator's live preview of the frame.
            fetched = driver.execute_async_script(
                "const done = arguments[arguments.length - 1];"
                "fetch(arguments[0]).then(r => done([r.status, r.headers.get('Content-Type'),"
                " r.headers.get('X-Tessera-Final')])).catch(e => done([0, String(e), '']));",
                src)
            self.assertEqual(fetched, [200, "image/png", "0"])

            # The priority box and its button.
            box = job_row().find_element(By.CSS_SELECTOR, "input.priority-input")
            box.clear()
            box.send_keys("7")
            job_row().find_element(By.CSS_SELECTOR, "button.set-priority").click()
            wait_for("priority 7", lambda: get_json(f"{base}/api/jobs/{job}")["priority"] == 7,
                     on_timeout=logs)

            # Cancel with the job's button: the page and the API say CANCELLED.
            job_row().find_element(By.CSS_SELECTOR, "button.cancel").click()
            wait_for("the job to show CANCELLED", lambda: row_text(".state") == "CANCELLED",
                     on_timeout=logs)
            status = get_json(f"{base}/api/jobs/{job}")
            self.assertEqual(status["state"], "CANCELLED")
            self.assertLess(status["tasks_done"], status["tasks_total"])
            self.assertFalse(job_row().find_element(By.CSS_SELECTOR, "button.cancel").is_enabled())
            self.assertTrue(job_row().find_element(By.CSS_SELECTOR, "button.retry").is_enabled())

            # Disable the worker with its button.
            worker_row = '#workers tr[data-worker="w1"]'
            driver.find_element(By.CSS_SELECTOR, f"{worker_row} button.disable").click()
            wait_for("the worker disabled", lambda: get_json(f"{base}/api/workers")
                     ["workers"][0]["disabled"], on_timeout=logs)
            wait_for("the Enable button", lambda: driver.find_element(
                By.CSS_SELECTOR, f"{worker_row} button.enable").is_displayed(), on_timeout=logs)
            self.assertIn(driver.find_element(By.CSS_SELECTOR, f"{worker_row} .state").text,
                          ("disabled", "draining"))
            self.assertFalse(driver.find_element(By.ID, "message").is_displayed(),
                             driver.find_element(By.ID, "message").text)
            ok = True
        finally:
            if driver is not None:
                if not ok:
                    with contextlib.suppress(Exception):
                        driver.save_screenshot(str(farm.dir / "failure.png"))
                with contextlib.suppress(Exception):
                    driver.quit()
            farm.finish(ok, kept="logs, outputs and a screenshot")


def main():
    parser = farm_argument_parser(__doc__.splitlines()[0])
    parser.add_argument("--chromium", default="/usr/bin/chromium", help="the browser")
    parser.add_argument("--chromedriver", default="/usr/bin/chromedriver",
                        help="its WebDriver (package chromium-driver)")
    args, rest = parser.parse_known_args()
    vars(ARGS).update(vars(args))
    for tool in (ARGS.chromium, ARGS.chromedriver):
        if not os.access(tool, os.X_OK):
            sys.exit(f"dashboard_browser_test: {tool} is missing: install chromium and "
                     "chromium-driver (deploy/setup.sh)")
    # ctest stops a test that runs too long with SIGTERM: clean up as after a failure.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit("dashboard_browser_test: terminated"))
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
