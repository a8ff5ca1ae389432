#!/usr/bin/env python3
"""The dashboard in a real browser: a master with CURVE keys, a worker and the CLI as real
processes on loopback, and the page opened in headless Chromium (Debian's chromium and
chromium-driver, through python3-selenium). From the page's DOM it checks that a running job's
progress and preview update, that its view shows its submitted and started times, a unit
rendering on the worker, the worker's share and the job's log, that the page is read-only without
a token, that a token of another key is refused when it cancels the job and is shown no worker
buttons, and that the owner's token cancels it (then its finished time shows). A sequence's
frames show their states, and one selected shows its own view. The worker's owner (the client key
of the worker key's name) drains, enables, disables (its units go back) and enables it from the
page. Then, with a job of a 60-character name running and an admin signed in, it checks the
layout at 1024, 1280 and 1600 px wide viewports: no table cell's content is clipped and every
table fits its card (the tables' .table-wrap would scroll sideways otherwise, never the page),
every visible button and input lies inside the viewport once scrolled into view, and the error
plot is an SVG at least 300 px wide and tall with labelled log axes and the job's error record
drawn. Every wait is bounded; every process is killed by PID at the end; a screenshot is left in
the build folder. (Helpers: dashboard_browser_util.py; the job view and worker checks:
dashboard_browser_views.py.)

Usage: dashboard_browser_test.py BUILD_DIR SOURCE_DIR
With RAYFARM_SCREENSHOTS=DIR set, the whole page at 1024 and 1600 px is saved to
DIR/dashboard-1024.png and DIR/dashboard-1600.png, and a sequence with a frame's view open to
DIR/dashboard-sequence.png (docs/images/ keeps them).
"""
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

from dashboard_browser_util import (accept_confirm, attribute, check, check_layout, click, text,
                                    wait_for)
from dashboard_browser_views import (check_finished_detail, check_no_worker_buttons,
                                     check_running_detail, check_sequence, check_worker_controls,
                                     count)

BUILD, SOURCE = sys.argv[1], sys.argv[2]
processes = []


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(argv, log):
    p = subprocess.Popen(argv, stdout=open(log, "w"), stderr=subprocess.STDOUT,
                         start_new_session=True)
    processes.append(p)
    return p


def cli(*args, key=None):
    argv = [os.path.join(BUILD, "cli/rayfarm"), *args]
    if key:
        argv += ["--master", CLIENT, "--key", os.path.join(KEYS, "own", key + ".key_secret"),
                 "--master-key", os.path.join(KEYS, "master.key")]
    out = subprocess.run(argv, capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        raise AssertionError(f"rayfarm {' '.join(args)} failed: {out.stderr}")
    return out.stdout.strip()


def sign_in(driver, token, badge):
    """Signs out whoever is signed in, then in with `token`; `badge`: what the page then says."""
    if driver.find_element(By.ID, "signout").is_displayed():
        driver.find_element(By.ID, "signout").click()
        wait_for(driver, "signed out", lambda d: text(d, "#who") == "read-only")
    driver.find_element(By.ID, "token").send_keys(token)
    driver.find_element(By.ID, "signin-button").click()
    wait_for(driver, badge + " signed in", lambda d: text(d, "#who") == badge)


def main():
    global KEYS, CLIENT
    work = tempfile.mkdtemp(prefix="rayfarm-dashboard-")
    KEYS = os.path.join(work, "keys")
    worker_port, client_port, http_port = free_port(), free_port(), free_port()
    CLIENT = f"tcp://127.0.0.1:{client_port}"
    driver = None
    try:
        # Keys: the master's, client keys (alice submits, bob does not own the job, root is an
        # admin), a worker's, w1, also listed as a client: w1's owner, who may drain it.
        cli("keygen", "--dir", KEYS, "--name", "master")
        for name, allow in (("alice", ["clients"]), ("bob", ["clients"]), ("root", ["clients"]),
                            ("w1", ["workers", "clients"])):
            cli("keygen", "--dir", os.path.join(KEYS, "own"), "--name", name)
            for folder in allow:
                os.makedirs(os.path.join(KEYS, folder), exist_ok=True)
                shutil.copy(os.path.join(KEYS, "own", name + ".key"), os.path.join(KEYS, folder))
        master = start([os.path.join(BUILD, "master/rayfarm-master"),
                        "--worker-endpoint", f"tcp://127.0.0.1:{worker_port}",
                        "--client-endpoint", CLIENT, "--data-dir", os.path.join(work, "data"),
                        "--http-endpoint", f"127.0.0.1:{http_port}",
                        "--key", os.path.join(KEYS, "master.key_secret"),
                        "--worker-keys", os.path.join(KEYS, "workers"),
                        "--client-keys", os.path.join(KEYS, "clients"), "--admin-clients", "root",
                        "--image-interval-ms", "300"], os.path.join(work, "master.log"))
        deadline = time.time() + 20
        while "master listening" not in open(os.path.join(work, "master.log")).read():
            check(time.time() < deadline and master.poll() is None,
                  "the master did not start:\n" + open(os.path.join(work, "master.log")).read())
            time.sleep(0.1)
        start([os.path.join(BUILD, "worker/rayfarm-worker"), "--master",
               f"tcp://127.0.0.1:{worker_port}", "--threads", "1", "--name", "w1",
               "--cache-dir", os.path.join(work, "cache"),
               "--key", os.path.join(KEYS, "own", "w1.key_secret"),
               "--master-key", os.path.join(KEYS, "master.key")], os.path.join(work, "worker.log"))
        # A job that runs for a while on one thread, in many small passes.
        job = cli("submit", os.path.join(SOURCE, "scenes/cornell-box/scene.json"), "--name",
                  "browser-test", "--res", "96x96", "--spp", "65536", "--pass-spp", "4",
                  key="alice")
        alice, bob = cli("token", key="alice"), cli("token", key="bob")
        root, owner = cli("token", key="root"), cli("token", key="w1")
        check(alice.startswith("rft1.") and len({alice, bob, root, owner}) == 4,
              f"odd tokens: {alice!r}, {bob!r}, {root!r}, {owner!r}")

        options = webdriver.ChromeOptions()
        options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
        for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                     "--disable-gpu", "--window-size=1400,1100", "--no-first-run"):
            options.add_argument(flag)
        driver = webdriver.Chrome(service=Service(shutil.which("chromedriver") or
                                                  "/usr/bin/chromedriver"), options=options)
        driver.set_script_timeout(20)
        driver.get(f"http://127.0.0.1:{http_port}/")

        # The job's row appears, and its progress grows.
        row = f'#jobs tbody tr[data-job="{job}"]'
        percent = lambda d: float((text(d, row + " .percent") or "0%").rstrip("%"))
        wait_for(driver, "the job's row", lambda d: text(d, row) is not None)
        first = wait_for(driver, "the job running", lambda d: percent(d) > 0 and percent(d))
        wait_for(driver, "the progress growing", lambda d: percent(d) > first)
        check(text(driver, "#who") == "read-only", "signed in without a token")
        check("alice" in text(driver, row), "the owner is not shown")
        wait_for(driver, "the worker", lambda d: "w1" in (text(d, "#workers tbody") or ""))

        # Its detail: the preview loads, then changes as passes merge.
        click(driver, row)
        loaded = lambda d: d.execute_script(
            "const i = document.getElementById('preview');"
            "return i.complete && i.naturalWidth > 0 ? i.dataset.version : null;")
        version = wait_for(driver, "the preview", loaded)
        width = driver.execute_script("return document.getElementById('preview').naturalWidth")
        check(width == 96, f"the preview is {width} pixels wide, not 96")
        wait_for(driver, "the preview updating", lambda d: loaded(d) not in (None, version))
        # Its view: times, units, the worker's share, the log; no worker buttons without a token.
        check_running_detail(driver, job)
        check_no_worker_buttons(driver, None, "a reader without a token")
        check(not driver.find_element(By.ID, "cancel").is_enabled(),
              "cancel is offered without a token")
        # Without a token the API refuses the action itself, not only the button.
        status = driver.execute_async_script(
            "const done = arguments[arguments.length - 1];"
            f"fetch('/api/jobs/{job}/cancel', {{method: 'POST'}}).then(r => done(r.status));")
        check(status == 401, f"a cancel without a token got HTTP {status}")

        # Bob's token: signed in, but not the job's owner: the button stays off, and a cancel
        # sent anyway is refused, with the reason on the page.
        sign_in(driver, bob, "key bob")
        check_no_worker_buttons(driver, bob, "bob")  # neither w1's key nor an admin
        check(not driver.find_element(By.ID, "cancel").is_enabled(),
              "cancel is offered to a key that does not own the job")
        # Enabled and clicked in one turn of the page's loop, which re-disables it every second.
        driver.execute_script("setTimeout(() => { const b = document.getElementById('cancel');"
                              " b.disabled = false; b.click(); }, 0);")
        accept_confirm(driver)
        wait_for(driver, "bob's cancel refused",
                 lambda d: "belongs to key 'alice'" in (text(d, "#message") or ""))
        check(attribute(driver, row, "data-state") == "running",
              "the job stopped running after a refused cancel")

        # Alice's token cancels it.
        sign_in(driver, alice, "key alice")
        wait_for(driver, "cancel offered to the owner",
                 lambda d: d.find_element(By.ID, "cancel").is_enabled())
        driver.save_screenshot(os.path.join(BUILD, "dashboard-screenshot.png"))
        driver.find_element(By.ID, "cancel").click()
        accept_confirm(driver)
        wait_for(driver, "the job cancelled",
                 lambda d: attribute(d, row, "data-state") == "cancelled")
        state = json.loads(cli("status", job, "--json", key="alice"))
        check(state.get("state") in ("cancelled", "JOB_CANCELLED"), f"the CLI says {state}")
        check_finished_detail(driver, job)

        # Over, it offers Retry and Delete instead: a retry runs it again, from its first sample.
        wait_for(driver, "retry offered on the cancelled job",
                 lambda d: d.find_element(By.ID, "retry").is_displayed() and
                 d.find_element(By.ID, "retry").is_enabled())
        check(not driver.find_element(By.ID, "cancel").is_enabled(), "cancel offered on a job over")
        driver.find_element(By.ID, "retry").click()
        wait_for(driver, "the job queued again",
                 lambda d: attribute(d, row, "data-state") in ("queued", "running"))
        state = json.loads(cli("status", job, "--json", key="alice"))
        check(state.get("state") in ("queued", "running", "JOB_QUEUED", "JOB_RUNNING"),
              f"after a retry the CLI says {state}")
        wait_for(driver, "cancel offered again", lambda d: d.find_element(By.ID, "cancel").is_enabled())
        driver.find_element(By.ID, "cancel").click()
        accept_confirm(driver)
        wait_for(driver, "the retried job cancelled",
                 lambda d: attribute(d, row, "data-state") == "cancelled")
        # Delete: asked to confirm, then the job and its folder are gone.
        wait_for(driver, "delete offered", lambda d: d.find_element(By.ID, "remove").is_enabled())
        driver.find_element(By.ID, "remove").click()
        accept_confirm(driver)
        wait_for(driver, "the job's row gone", lambda d: text(d, row) is None)
        gone = subprocess.run([os.path.join(BUILD, "cli/rayfarm"), "status", job, "--master",
                               CLIENT, "--key", os.path.join(KEYS, "own", "alice.key_secret"),
                               "--master-key", os.path.join(KEYS, "master.key")],
                              capture_output=True, text=True, timeout=60)
        check(gone.returncode == 1 and "unknown job" in gone.stderr,
              f"after delete the CLI says {gone.returncode}: {gone.stderr}")

        # A sequence of three small frames: a tile per frame with its state, one frame's view.
        seq = cli("submit", os.path.join(SOURCE, "scenes/animated-box/scene.json"), "--name",
                  "browser-sequence", "--frames", "1-3", "--res", "32x32", "--spp", "16",
                  "--pass-spp", "4", key="alice")
        wait_for(driver, "the sequence's row", lambda d: text(d, f'#jobs tbody tr[data-job="{seq}"]'))
        check_sequence(driver, seq, [1, 2, 3])
        cli("rm", seq, key="alice")
        wait_for(driver, "the sequence gone", lambda d: text(d, f'#jobs tbody tr[data-job="{seq}"]') is None)

        # The layout, with a realistic long job name (60 characters) running, alice signed in.
        name = "kitchen-interior_lookdev-v012_final-4k_cam03-denoise-off-tk7"
        check(len(name) == 60, f"the long name has {len(name)} characters")
        long_job = cli("submit", os.path.join(SOURCE, "scenes/cornell-box/scene.json"), "--name",
                       name, "--res", "96x96", "--spp", "65536", "--pass-spp", "4",
                       "--target-error", "3e-4", key="alice")
        long_row = f'#jobs tbody tr[data-job="{long_job}"]'
        wait_for(driver, "the long-named job's row", lambda d: text(d, long_row) is not None)
        click(driver, long_row)
        wait_for(driver, "the long-named job's detail",
                 lambda d: attribute(d, "#detail", "data-job") == long_job)
        wait_for(driver, "its error plot with a few points",
                 lambda d: int(attribute(d, "#error-plot", "data-points") or 0) >= 4)
        wait_for(driver, "cancel offered on it",
                 lambda d: d.find_element(By.ID, "cancel").is_enabled())
        # w1's owner drains, enables, disables and enables it again, the job running on it.
        sign_in(driver, owner, "key w1")
        check_worker_controls(driver, long_job)
        # An admin may change any worker, and act on anyone's job; the layout is checked with
        # both the job's and the worker's buttons shown.
        sign_in(driver, root, "key root (admin)")
        wait_for(driver, "the worker's buttons for an admin",
                 lambda d: count(d, '#workers tbody button[data-action="drain"]') == 1)
        wait_for(driver, "cancel offered to an admin",
                 lambda d: d.find_element(By.ID, "cancel").is_enabled())
        # Sorting and filtering: a second job, held paused; the filter keeps the jobs whose id,
        # name, owner or state hold its words; a header sorts by its column, again the other way.
        short_job = cli("submit", os.path.join(SOURCE, "scenes/cornell-box/scene.json"), "--name",
                        "aaa-turntable", "--res", "32x32", "--spp", "64", "--paused", key="alice")
        rows = ("return [...document.querySelectorAll('#jobs tbody tr')]"
                ".map((r) => r.dataset.job);")
        wait_for(driver, "both jobs listed", lambda d: set(d.execute_script(rows)) ==
                 {long_job, short_job})
        driver.find_element(By.ID, "job-filter").send_keys("kitchen")
        wait_for(driver, "the filter keeps the long-named job alone",
                 lambda d: d.execute_script(rows) == [long_job])
        driver.find_element(By.ID, "job-filter").clear()
        driver.find_element(By.ID, "job-filter").send_keys("paused alice")
        wait_for(driver, "the filter reads the state and the owner",
                 lambda d: d.execute_script(rows) == [short_job])
        driver.find_element(By.ID, "job-filter").send_keys(" nomatch")
        wait_for(driver, "no job matches", lambda d: d.execute_script(rows) == [] and
                 d.find_element(By.ID, "no-match").is_displayed())
        driver.find_element(By.ID, "job-filter").clear()
        driver.execute_script("document.getElementById('job-filter')"
                              ".dispatchEvent(new Event('input'));")
        click(driver, '#jobs th[data-sort="name"]')
        wait_for(driver, "sorted by name", lambda d: d.execute_script(rows) == [short_job, long_job])
        check(attribute(driver, '#jobs th[data-sort="name"]', "aria-sort") == "ascending",
              "the sorted header says so")
        click(driver, '#jobs th[data-sort="name"]')
        wait_for(driver, "sorted by name the other way",
                 lambda d: d.execute_script(rows) == [long_job, short_job])
        click(driver, long_row)

        # Its target error, from the job's status, drawn as a line on the plot.
        wait_for(driver, "the target error on the plot",
                 lambda d: float(attribute(d, "#error-plot", "data-target") or 0) == 3e-4)
        check(driver.execute_script("return document.querySelector('#error-plot svg')"
                                    ".textContent.includes('target error');"),
              "the plot's legend names the target error")
        check_layout(driver, long_job, name)
        print(f"dashboard browser test passed (job {job}); screenshot in "
              f"{os.path.join(BUILD, 'dashboard-screenshot.png')}")
        return 0
    finally:
        if driver is not None:
            driver.quit()
        for p in processes:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()
        if os.environ.get("RAYFARM_KEEP_TEST_DIR"):
            print("kept", work)
        else:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    try:
        sys.exit(main())
    except AssertionError as e:
        print("FAILED:", e, file=sys.stderr)
        sys.exit(1)
