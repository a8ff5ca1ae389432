"""The dashboard browser test's checks of the job view and the worker controls
(dashboard_browser_test.py runs them): a job's submitted, started and finished times, its units,
what each worker rendered of it and its log (/api/jobs/ID/detail); a sequence's frames, one
selected for its own view; a worker drained, enabled, disabled and enabled again from the page, by
its key's owner, and no buttons for a key that may not.
"""
import os
import re
import time

from dashboard_browser_util import (api_status, attribute, check, click, click_then_confirm,
                                    text, viewport, wait_for)

CLOCK = re.compile(r"\d\d:\d\d:\d\d")
YEAR = time.strftime("%Y")


def count(d, selector):
    return d.execute_script("return document.querySelectorAll(arguments[0]).length;", selector)


def texts(d, selector):
    return d.execute_script("return [...document.querySelectorAll(arguments[0])]"
                            ".map((e) => e.textContent);", selector)


def fact(d, name, within="#facts"):
    return text(d, f'{within} [data-fact="{name}"]') or ""


def check_running_detail(d, job):
    """The selected job runs: its times, a unit rendering on w1, w1's share, its log."""
    row = f'#jobs tbody tr[data-job="{job}"]'
    shown = text(d, row + " td.submitted") or ""
    check(re.fullmatch(r"\d\d:\d\d", shown), f"the job's row says submitted {shown!r}")
    tip = attribute(d, row + " td.submitted", "title") or ""
    check(YEAR in tip and CLOCK.search(tip), f"the submitted cell's tooltip is {tip!r}")
    wait_for(d, "the job view", lambda d: attribute(d, "#job-detail", "data-job") == job and
             d.find_element("id", "job-detail").is_displayed())
    check(CLOCK.search(fact(d, "submitted")) and YEAR in
          (attribute(d, '#facts [data-fact="submitted"]', "title") or ""),
          f"submitted reads {fact(d, 'submitted')!r}")
    wait_for(d, "its start time and wait", lambda d: CLOCK.search(fact(d, "started")) and
             "waited" in fact(d, "started"))
    check(fact(d, "finished") == "not yet", f"a running job's finished reads {fact(d, 'finished')!r}")
    rendering = '#units tbody tr[data-state="rendering"]'
    wait_for(d, "a unit rendering on w1", lambda d: "w1" in (text(d, rendering) or ""))
    unit = texts(d, rendering + " td")
    check(re.search(r"\d+–\d+ × \d+–\d+", unit[1]) and re.search(r"\d+–\d+", unit[2]),
          f"a rendering unit's row reads {unit}")
    check(int(text(d, '#unit-summary [data-count="rendering"] b') or 0) >= 1,
          f"the summary reads {text(d, '#unit-summary')!r}")
    wait_for(d, "w1's share of it", lambda d: d.execute_script(
        "return [...document.querySelectorAll('#shares tbody tr')].some((r) =>"
        " /\\bw1\\b/.test(r.cells[0].textContent) && Number(r.cells[1].textContent) > 0);"))
    wait_for(d, "its log's started line", lambda d: any(
        "start" in t.lower() for t in texts(d, "#job-log li.log-line .log-text")))
    stamp = text(d, "#job-log li.log-line time") or ""
    check(CLOCK.fullmatch(stamp), f"a log line's time reads {stamp!r}")
    print(f"job view: submitted {fact(d, 'submitted')}, started {fact(d, 'started')}, "
          f"{count(d, '#units tbody tr')} units listed, {count(d, '#job-log li.log-line')} log lines")


def check_finished_detail(d, job):
    """The selected job is over: its finished time and run, no units, its log still there."""
    wait_for(d, "its finished time", lambda d: attribute(d, "#job-detail", "data-job") == job and
             CLOCK.search(fact(d, "finished")) and "ran" in fact(d, "finished"))
    wait_for(d, "no units once it is over", lambda d: count(d, "#units tbody tr") == 0 and
             d.find_element("id", "no-units").is_displayed())
    check(any("start" in t.lower() for t in texts(d, "#job-log li.log-line .log-text")),
          "the finished job's log lost its started line")
    print(f"job view over: finished {fact(d, 'finished')}; log: "
          f"{texts(d, '#job-log li.log-line .log-text')[-1]!r}")


def worker_id(d):
    return d.execute_script("const r = document.querySelector('#workers tbody tr');"
                            "return r ? r.dataset.worker : null;")


def check_no_worker_buttons(d, token, who):
    """A reader whose token may not change w1 sees no buttons, the API says so, and refuses."""
    time.sleep(1.5)  # a refresh with the session
    check(count(d, "#workers tbody button") == 0, f"{who} is shown worker buttons")
    status, body = api_status(d, "GET", "/api/workers", token)
    check(status == 200 and all(w.get("can_manage") is False for w in body["workers"]),
          f"/api/workers for {who}: {status} {body}")
    status, body = api_status(d, "POST", f"/api/workers/{worker_id(d)}/drain", token)
    check(status == (403 if token else 401), f"a drain by {who} got HTTP {status}: {body}")


def worker_state(d):
    return attribute(d, "#workers tbody tr", "data-state")


def check_worker_controls(d, job):
    """Signed in as w1's owner, with `job` selected and running on w1 alone."""
    wid = worker_id(d)
    row = f'#workers tbody tr[data-worker="{wid}"]'
    button = lambda action: f'{row} button[data-action="{action}"]'
    wait_for(d, "w1's Drain and Disable", lambda d: count(d, button("drain")) == 1 and
             count(d, button("disable")) == 1 and count(d, button("enable")) == 0)
    click_then_confirm(d, button("drain"))
    wait_for(d, "w1 draining", lambda d: worker_state(d) in ("draining", "drained") and
             "draining" in (text(d, "#message") or ""))
    wait_for(d, "w1 drained (its units finished)", lambda d: worker_state(d) == "drained")
    check(count(d, button("drain")) == 0 and count(d, button("enable")) == 1 and
          count(d, button("disable")) == 1, "a drained worker's buttons are not Enable and Disable")
    check(text(d, row + " td.units") == "–", f"a drained w1 holds {text(d, row + ' td.units')}")
    click(d, button("enable"))
    wait_for(d, "w1 enabled", lambda d: attribute(d, row, "data-control") == "enabled" and
             worker_state(d) in ("busy", "idle"))
    wait_for(d, "w1 rendering again", lambda d: worker_state(d) == "busy")
    click_then_confirm(d, button("disable"))
    wait_for(d, "w1 disabled", lambda d: worker_state(d) == "disabled" and
             "back in the queue" in (text(d, "#message") or ""))
    check(text(d, row + " td.units") == "–", f"a disabled w1 holds {text(d, row + ' td.units')}")
    check(count(d, button("enable")) == 1 and count(d, button("drain")) == 0 and
          count(d, button("disable")) == 0, "a disabled worker's only button is not Enable")
    # Its units went back: the job's view has none rendering, and it says so while w1 is out.
    wait_for(d, "no unit of the job rendering", lambda d: attribute(
        d, "#job-detail", "data-job") == job and count(d, '#units tbody tr[data-state="rendering"]') == 0)
    time.sleep(1.5)
    check(worker_state(d) == "disabled" and text(d, row + " td.units") == "–",
          "a disabled worker took a unit")
    print(f"worker controls: {text(d, '#message')!r}; queued "
          f"{text(d, '#unit-summary [data-count=queued] b')}")
    click(d, button("enable"))
    wait_for(d, "w1 enabled again", lambda d: attribute(d, row, "data-control") == "enabled")
    wait_for(d, "the job's units rendering again", lambda d: "w1" in (
        text(d, '#units tbody tr[data-state="rendering"]') or ""))


def check_sequence(d, seq, frames):
    """A sequence selected: a tile per frame with its state; a frame's own view; back again."""
    click(d, f'#jobs tbody tr[data-job="{seq}"]')
    wait_for(d, "the sequence's frames", lambda d: attribute(d, "#detail", "data-job") == seq and
             count(d, "#frames .frame") == len(frames))
    states = texts(d, "#frames .frame .frame-caption .state")
    check(len(states) == len(frames) and all(states), f"the frames' states read {states}")
    wait_for(d, "the sequence's own view", lambda d: attribute(d, "#job-detail", "data-job") == seq)
    frame = attribute(d, f'#frames .frame[data-frame="{frames[1]}"]', "data-job") or ""
    check(frame.startswith(seq + "."), f"frame {frames[1]}'s job is {frame!r}")
    click(d, f'#frames .frame[data-job="{frame}"]')
    wait_for(d, f"frame {frames[1]}'s view", lambda d: attribute(
        d, "#job-detail", "data-job") == frame and f"Frame {frames[1]}" in (text(d, "#frame-title") or ""))
    check(attribute(d, f'#frames .frame[data-job="{frame}"]', "class").split().count("selected") == 1,
          "the selected frame is not marked")
    check(CLOCK.search(fact(d, "submitted", "#frame-facts")), "the frame's submitted time is not shown")
    wait_for(d, "the frame done, with its finished time", lambda d: attribute(
        d, f'#frames .frame[data-job="{frame}"]', "data-state") == "done" and
        fact(d, "state", "#frame-facts") == "done" and CLOCK.search(fact(d, "finished", "#frame-facts")))
    wait_for(d, "every frame done", lambda d: texts(d, "#frames .frame .frame-caption .state") ==
             ["done"] * len(frames))
    # The frame's log as the API gives it (a line each).
    status, body = api_status(d, "GET", f"/api/jobs/{frame}/detail")
    check(status == 200, f"the frame's detail: HTTP {status}")
    wait_for(d, "the frame's log", lambda d: count(d, "#job-log li.log-line") == len(body["log"]))
    shots = os.environ.get("RAYFARM_SCREENSHOTS")
    if shots:  # the sequence with one frame's view open, for docs/farm.md
        size = d.execute_script("return [window.innerWidth, window.innerHeight];")
        viewport(d, 1280, 1200)
        time.sleep(1.5)  # the contact sheet of the three frames, redrawn at this width
        d.execute_script("document.getElementById('detail').scrollIntoView();")
        time.sleep(0.3)
        os.makedirs(shots, exist_ok=True)
        d.save_screenshot(os.path.join(shots, "dashboard-sequence.png"))
        viewport(d, *size)
    click(d, "#frame-close")
    wait_for(d, "the whole sequence's view again", lambda d: attribute(d, "#job-detail", "data-job") == seq
             and not d.find_element("id", "frame-head").is_displayed())
    print(f"sequence {seq}: frame {frame}'s view, finished {fact(d, 'finished', '#frame-facts')}")
