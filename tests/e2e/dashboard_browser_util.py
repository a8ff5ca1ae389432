"""The dashboard browser test's page helpers (dashboard_browser_test.py): reading and clicking the
page's elements in one script each (its tables are drawn again every second), bounded waits, and
the layout checks at 1024, 1280 and 1600 px (no table cell clips its content, every table fits its
card, every button and input lies in the window, the error plot is drawn with labelled axes).
"""
import os
import time

from selenium.common.exceptions import (NoSuchElementException, StaleElementReferenceException,
                                        TimeoutException)
from selenium.webdriver.support import expected_conditions as EC
from selenium.webdriver.support.ui import WebDriverWait

WAIT = 45  # seconds, for anything the page should show


def check(condition, message):
    if not condition:
        raise AssertionError(message)


# The page redraws its tables every second: elements are read and clicked in one script, so that
# none goes stale between finding it and using it.
def text(d, selector):
    return d.execute_script("const e = document.querySelector(arguments[0]);"
                            "return e ? e.textContent : null;", selector)


def attribute(d, selector, name):
    return d.execute_script("const e = document.querySelector(arguments[0]);"
                            "return e ? e.getAttribute(arguments[1]) : null;", selector, name)


def click(d, selector):
    d.execute_script("document.querySelector(arguments[0]).click();", selector)


def click_then_confirm(d, selector):
    """Clicks `selector` from a timer, so that the click's confirmation does not block the script
    that clicks, and accepts the confirmation."""
    d.execute_script("setTimeout(() => document.querySelector(arguments[0]).click(), 0);", selector)
    accept_confirm(d)


def api_status(d, method, path, token=None):
    """The HTTP status and JSON body of a request the page's origin sends, with `token` if given."""
    return d.execute_async_script(
        "const [method, path, token, done] = arguments;"
        "const headers = token ? {Authorization: 'Bearer ' + token} : {};"
        "fetch(path, {method, headers, body: method === 'POST' ? '' : undefined})"
        "  .then(async (r) => done([r.status, await r.json().catch(() => null)]))"
        "  .catch((e) => done([0, String(e)]));", method, path, token)


def accept_confirm(driver):
    try:
        WebDriverWait(driver, 10).until(EC.alert_is_present()).accept()
    except TimeoutException:
        raise AssertionError("the page asked for no confirmation") from None


def wait_for(driver, what, predicate):
    try:
        return WebDriverWait(driver, WAIT, poll_frequency=0.2,
                             ignored_exceptions=(NoSuchElementException,
                                                 StaleElementReferenceException)
                             ).until(lambda d: predicate(d))
    except TimeoutException:
        raise AssertionError(f"the page did not show {what} within {WAIT} s") from None


# What the page shows wrong at the current viewport width: a list of problems, empty when none.
LAYOUT_PROBLEMS = """
const problems = [];
const root = document.documentElement;
const vw = root.clientWidth, vh = window.innerHeight;
if (root.scrollWidth > vw + 1) problems.push(`the page is ${root.scrollWidth} px wide in a ${vw} px window`);
const show = (e) => (e.id ? '#' + e.id : e.tagName.toLowerCase()) +
  (e.textContent ? ' "' + e.textContent.trim().slice(0, 40) + '"' : '');
for (const table of document.querySelectorAll('table')) {
  const wrap = table.closest('.table-wrap');
  if (!wrap) { problems.push(`table #${table.id} has no .table-wrap`); continue; }
  const overflowX = getComputedStyle(wrap).overflowX;
  if (!['auto', 'scroll'].includes(overflowX)) problems.push(`#${table.id}'s wrap does not scroll (${overflowX})`);
  // Scrolling is the fallback: at these widths every table fits without it.
  if (wrap.scrollWidth > wrap.clientWidth + 1)
    problems.push(`table #${table.id} is ${wrap.scrollWidth} px wide in a ${wrap.clientWidth} px container ` +
      '(columns ' + [...table.querySelectorAll('th')].map((th) => th.textContent + ' ' +
                                                           Math.round(th.offsetWidth)).join(', ') + ')');
  const card = wrap.closest('.card').getBoundingClientRect(), r = wrap.getBoundingClientRect();
  if (r.left < card.left - 0.5 || r.right > card.right + 0.5) problems.push(`#${table.id}'s wrap sticks out of its card`);
  for (const cell of table.querySelectorAll('th, td')) {
    if (cell.scrollWidth > cell.clientWidth + 1 || cell.scrollHeight > cell.clientHeight + 1)
      problems.push(`a cell of #${table.id} clips its content: ${show(cell)}`);
    const c = cell.getBoundingClientRect();
    if (c.right > r.right + 0.5 && wrap.scrollWidth <= wrap.clientWidth + 1)
      problems.push(`a cell of #${table.id} lies outside its container: ${show(cell)}`);
  }
}
for (const e of document.querySelectorAll('button, input, #detail h2, .detail-body > *')) {
  if (!e.getClientRects().length) continue;  // hidden
  e.scrollIntoView({block: 'nearest', inline: 'nearest'});
  const b = e.getBoundingClientRect();
  if (b.left < -0.5 || b.top < -0.5 || b.right > vw + 0.5 || b.bottom > vh + 0.5)
    problems.push(`${show(e)} is not inside the ${vw}x${vh} window: ${JSON.stringify(b)}`);
  const card = e.closest('.card');
  if (card) {
    const cb = card.getBoundingClientRect();
    if (b.left < cb.left - 0.5 || b.right > cb.right + 0.5) problems.push(`${show(e)} sticks out of its card`);
  }
}
window.scrollTo(0, 0);
return problems;
"""

# The error plot: its size, its axis and tick labels, the points drawn.
PLOT = """
const svg = document.querySelector('#error-plot svg');
if (!svg) return null;
const r = svg.getBoundingClientRect();
const texts = (sel) => [...svg.querySelectorAll(sel)].map((t) => t.textContent);
const line = svg.querySelector('polyline.series-est');
return {width: r.width, height: r.height, x_label: texts('.x-label').join(), y_label: texts('.y-label').join(),
        x_ticks: texts('.x-tick'), y_ticks: texts('.y-tick'),
        points: line ? line.getAttribute('points').trim().split(/\\s+/).length : 0,
        card_width: document.getElementById('detail').getBoundingClientRect().width};
"""


def viewport(driver, width, height):
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1,
                            "mobile": False})


def check_layout(driver, job, name):
    row = f'#jobs tbody tr[data-job="{job}"]'
    shots = os.environ.get("RAYFARM_SCREENSHOTS")
    for width in (1600, 1280, 1024):
        viewport(driver, width, 900)
        time.sleep(1.5)  # a redraw of the tables, and of the plot at its new size
        # The whole page in the window, so that the screenshot shows all of it.
        height = min(2400, driver.execute_script("return document.documentElement.scrollHeight"))
        viewport(driver, width, max(height, 700))
        time.sleep(0.5)
        inner = driver.execute_script("return window.innerWidth")
        check(inner == width, f"the window is {inner} px wide, not {width}")
        check(text(driver, row + " .job-name") == name,
              f"at {width} px the job's name reads {text(driver, row + ' .job-name')!r}")
        problems = driver.execute_script(LAYOUT_PROBLEMS)
        # With the window as tall as the page, buttons fit anyway: check them in a short one too.
        viewport(driver, width, 700)
        time.sleep(0.3)
        problems += driver.execute_script(LAYOUT_PROBLEMS)
        check(not problems, f"at {width} px: " + "; ".join(dict.fromkeys(problems)))
        plot = driver.execute_script(PLOT)
        check(plot is not None, f"at {width} px there is no error plot SVG")
        check(plot["width"] >= 300 and plot["height"] >= 300,
              f"at {width} px the error plot is {plot['width']}x{plot['height']} px")
        check("time" in plot["x_label"] and "(s)" in plot["x_label"],
              f"the plot's x axis label is {plot['x_label']!r}")
        check("relative MSE" in plot["y_label"], f"the plot's y axis label is {plot['y_label']!r}")
        check(len(plot["x_ticks"]) >= 2 and len(plot["y_ticks"]) >= 2,
              f"the plot's tick labels: x {plot['x_ticks']}, y {plot['y_ticks']}")
        check(plot["points"] >= 2, f"the plot draws {plot['points']} points")
        print(f"{width} px: layout fine; error plot {plot['width']:.0f}x{plot['height']:.0f} px, "
              f"x ticks {plot['x_ticks']}, y ticks {plot['y_ticks']}, {plot['points']} points")
        if shots and width in (1024, 1600):
            viewport(driver, width, max(height, 700))
            time.sleep(1.2)
            os.makedirs(shots, exist_ok=True)
            driver.save_screenshot(os.path.join(shots, f"dashboard-{width}.png"))
