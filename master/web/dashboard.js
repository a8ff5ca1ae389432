// rayfarm's dashboard: polls the master's JSON API (docs/farm.md, "The dashboard") once a second
// and draws jobs, the selected job's image, error plot, frames, units and log, and the workers.
// Actions send the token from `rayfarm token` as a bearer token; without one the page is
// read-only. The script comes in parts, which master/CMakeLists.txt joins in this order into the
// one /dashboard.js the master serves: this file (the state, the helpers, the jobs, the selected
// job, the session and the loop), error_plot.js, job_detail.js (units, workers' shares, log,
// frames) and workers.js (the workers and their controls).
"use strict";

const state = {
  token: localStorage.getItem("rayfarm-token") || "",
  session: null,
  selected: null,        // job id
  shown: {},             // what the selected job's images were drawn from
  thumbs: new Map(),     // frame job id -> object URL, or null while it loads
  loads: 0,              // images loaded for the selected job (the preview's data-version)
  busy: false,
  plot: { rows: [], target: 0 },  // the selected job's error record, drawn by drawErrorPlot
  sort: { key: null, ascending: true },  // the jobs table's order: the master's until a click
  lastJobs: null,  // the latest job list, drawn again when the filter or the order changes
  frame: null,     // the selected sequence's frame whose units and log are shown (its job id)
};

const $ = (id) => document.getElementById(id);

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") e.className = v;
    else if (k.startsWith("data-")) e.setAttribute(k, v);
    else e[k] = v;
  }
  for (const c of children) e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return e;
}

async function api(path, options = {}) {
  const headers = Object.assign({}, options.headers || {});
  if (state.token) headers["Authorization"] = "Bearer " + state.token;
  const res = await fetch(path, Object.assign({}, options, { headers, cache: "no-store" }));
  if (!res.ok) {
    let message = "HTTP " + res.status;
    try { message = (await res.json()).error || message; } catch (e) { /* not JSON */ }
    const err = new Error(message);
    err.status = res.status;
    throw err;
  }
  return res;
}

async function apiJson(path, options) { return (await api(path, options)).json(); }

// A message above the jobs; `lost`: it says the master could not be read, and goes once it can.
function say(text, isError, lost) {
  const m = $("message");
  m.textContent = text;
  m.className = isError ? "error" : "";
  m.hidden = !text;
  if (lost) m.dataset.lost = "1"; else delete m.dataset.lost;
}

// ---- formatting -------------------------------------------------------------------------------

const STATES = { JOB_QUEUED: "queued", JOB_RUNNING: "running", JOB_DONE: "done",
                 JOB_FAILED: "failed", JOB_CANCELLED: "cancelled" };
function stateName(job) {
  const s = STATES[job.state] || "unknown";
  return job.paused && (s === "queued" || s === "running") ? "paused" : s;
}
function finished(job) { return ["done", "failed", "cancelled"].includes(STATES[job.state]); }

function duration(seconds) {
  if (!(seconds >= 0) || !isFinite(seconds)) return "–";
  if (seconds < 60) return seconds.toFixed(seconds < 10 ? 1 : 0) + " s";
  const m = Math.floor(seconds / 60), s = Math.round(seconds % 60);
  if (m < 60) return m + " min " + s + " s";
  return Math.floor(m / 60) + " h " + (m % 60) + " min";
}
function rate(x) {
  if (!(x > 0)) return "–";
  const units = [[1e9, "G"], [1e6, "M"], [1e3, "k"]];
  for (const [f, u] of units) if (x >= f) return (x / f).toFixed(2) + " " + u;
  return x.toFixed(0);
}
function sci(x) { return x >= 0 ? Number(x).toExponential(2) : "–"; }
function percentOf(job) {
  if (STATES[job.state] === "done") return 100;
  const total = Number(job.units_total), done = Number(job.units_done);
  if (total > 0) return 100 * done / total;
  if (job.frames_total > 0) return 100 * job.frames_done / job.frames_total;
  return 0;
}
function sppTotal(job) { return job.pass_spp * job.passes_total; }

// Times: the API's Unix milliseconds (64-bit, so strings; "0": not yet) in the browser's time
// zone, compact ("16:45" today, "Dec 5 16:45" before), in full for tooltips.
const MONTHS = ["Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec"];
function unixMs(v) { const t = Number(v || 0); return t > 0 && isFinite(t) ? t : 0; }
function pad2(n) { return String(n).padStart(2, "0"); }
function clock(ms, withSeconds) {
  if (!ms) return "–";
  const d = new Date(ms), now = new Date();
  const time = pad2(d.getHours()) + ":" + pad2(d.getMinutes()) + (withSeconds ? ":" + pad2(d.getSeconds()) : "");
  if (d.toDateString() === now.toDateString()) return time;
  return MONTHS[d.getMonth()] + " " + d.getDate() +
    (d.getFullYear() === now.getFullYear() ? "" : " " + d.getFullYear()) + " " + time;
}
// The compact time as lines: the day when not today, then the time.
function compactTime(ms) {
  const text = clock(ms), cut = text.lastIndexOf(" ");
  return cut < 0 ? [text] : [el("span", {}, text.slice(0, cut)), " ", el("span", {}, text.slice(cut + 1))];
}
function fullTime(ms) {
  if (!ms) return "";
  const d = new Date(ms);
  return d.getFullYear() + "-" + pad2(d.getMonth() + 1) + "-" + pad2(d.getDate()) + " " +
    pad2(d.getHours()) + ":" + pad2(d.getMinutes()) + ":" + pad2(d.getSeconds());
}
// A job's (or frame's) submitted, started and finished times, the wait and the run between them.
function jobTimes(job) {
  const submitted = unixMs(job.submitted_unix_ms), started = unixMs(job.started_unix_ms);
  const ended = unixMs(job.finished_unix_ms);
  return {
    submitted, started, finished: ended,
    wait: submitted && started ? (started - submitted) / 1000 : NaN,
    run: started && ended ? (ended - started) / 1000 : NaN,
  };
}

// ---- jobs -------------------------------------------------------------------------------------

function jobRow(job) {
  const pct = percentOf(job);
  const s = stateName(job);
  const tr = el("tr", { "data-job": job.job_id, "data-state": s },
    el("td", { class: "text", title: (job.name || job.job_id) + " (" + job.job_id + ")" },
       el("span", { class: "job-name" }, job.name || job.job_id),
       el("span", { class: "job-id" }, job.job_id)),
    el("td", {}, job.owner || "–"),
    el("td", {}, el("span", { class: "state " + s }, s)),
    el("td", { class: "num" }, job.priority),
    el("td", { class: "num submitted", title: "submitted " + fullTime(unixMs(job.submitted_unix_ms)) },
       ...compactTime(unixMs(job.submitted_unix_ms))),
    el("td", {}, job.frames_total > 0 ? job.frames_done + " / " + job.frames_total
                                      : ("frame" in job ? "frame " + job.frame : "–")),
    el("td", {}, job.frames_total > 0 ? "–" : job.spp_done + " / " + sppTotal(job)),
    el("td", {}, el("span", { class: "bar" + (s === "done" ? " done" : "") },
                    el("div", { style: "" })),
       el("span", { class: "percent" }, pct.toFixed(1) + "%")),
    el("td", { class: "num" }, finished(job) ? "–" : rate(job.samples_per_second)),
    el("td", { class: "num" }, finished(job) ? "–" : duration(job.eta_seconds)),
    el("td", { class: "num" }, sci(job.est_rel_mse)),
    el("td", { class: "text", title: job.error || "" },
       job.stop_reason || (job.error ? "error" : "–")));
  tr.querySelector(".bar > div").style.width = Math.min(100, pct).toFixed(1) + "%";
  if (job.job_id === state.selected) tr.classList.add("selected");
  tr.addEventListener("click", () => select(job.job_id));
  return tr;
}

// The jobs' order and filter, the user's: a click on a sortable header sorts by it (again: the
// other way), and the filter keeps the jobs whose id, name, owner or state holds its words.
const SORT_KEYS = {
  name: (j) => (j.name || j.job_id).toLowerCase(),
  owner: (j) => (j.owner || "").toLowerCase(),
  state: (j) => stateName(j),
  priority: (j) => j.priority,
  submitted: (j) => unixMs(j.submitted_unix_ms),
  progress: (j) => percentOf(j),
  rate: (j) => (finished(j) ? -1 : j.samples_per_second),
  eta: (j) => (finished(j) || !(j.eta_seconds >= 0) ? Infinity : j.eta_seconds),
  error: (j) => (j.est_rel_mse >= 0 ? j.est_rel_mse : Infinity),
};

function shownJobs(jobs) {
  const words = $("job-filter").value.toLowerCase().split(/\s+/).filter(Boolean);
  let out = jobs.filter((j) => {
    const hay = [j.job_id, j.name || "", j.owner || "", stateName(j)].join(" ").toLowerCase();
    return words.every((w) => hay.includes(w));
  });
  const key = SORT_KEYS[state.sort.key];
  if (key) {
    const dir = state.sort.ascending ? 1 : -1;
    // Stable: equal keys keep the master's order (the order of submission).
    out = out.map((j, i) => [j, i]).sort((a, b) => {
      const ka = key(a[0]), kb = key(b[0]);
      return ka < kb ? -dir : ka > kb ? dir : a[1] - b[1];
    }).map((p) => p[0]);
  }
  return out;
}

function drawJobs(list) {
  state.lastJobs = list;
  const body = $("jobs").querySelector("tbody");
  const shown = shownJobs(list.jobs);
  body.replaceChildren(...shown.map(jobRow));
  for (const th of $("jobs").querySelectorAll("th[data-sort]")) {
    const on = th.dataset.sort === state.sort.key;
    if (on) th.setAttribute("aria-sort", state.sort.ascending ? "ascending" : "descending");
    else th.removeAttribute("aria-sort");
  }
  $("no-jobs").hidden = list.jobs.length > 0;
  $("no-match").hidden = list.jobs.length === 0 || shown.length > 0;
  $("job-count").textContent = list.jobs.length ? "(" + list.jobs.length + ")" : "";
  $("farm").textContent = list.workers_total + " worker" + (list.workers_total === 1 ? "" : "s") +
    " connected" + (state.session ? " · " + state.session.build : "");
}

// ---- the selected job -------------------------------------------------------------------------

function select(id) {
  if (id !== state.selected) {
    clearImage($("preview"));
    state.plot = { rows: [], target: 0 };
    drawErrorPlot();
    for (const url of state.thumbs.values()) if (url) URL.revokeObjectURL(url);
    state.thumbs.clear();
    state.frame = null;
    clearJobDetail();
  }
  state.selected = id;
  state.shown = {};
  for (const tr of $("jobs").querySelectorAll("tbody tr")) {
    tr.classList.toggle("selected", tr.dataset.job === id);
  }
  refreshDetail();
}

function clearImage(img) {
  if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
  img.removeAttribute("src");
}

// Shows the image at `path` of job `id` in `img`, unless another job was selected meanwhile.
async function loadImage(img, id, path) {
  try {
    const blob = await (await api(path)).blob();
    if (id !== state.selected) return false;  // another job was selected meanwhile
    const old = img.src;
    img.src = URL.createObjectURL(blob);
    if (old.startsWith("blob:")) URL.revokeObjectURL(old);
    return true;
  } catch (e) {
    if (id === state.selected) clearImage(img);  // not written yet: no other job's image shown
    return false;
  }
}

// A figure of the selected job; `key` names it for scripts (data-fact), `title` is its tooltip.
function fact(name, value, key, title) {
  const dd = el("dd", key ? { "data-fact": key } : {}, value);
  if (title) dd.title = title;
  return [el("div", { class: "fact" }, el("dt", {}, name), dd)];
}
// The submitted, started and finished facts of a job (or frame), with the wait and the run.
function timeFacts(job) {
  const t = jobTimes(job);
  return [
    ...fact("Submitted", clock(t.submitted, true), "submitted", fullTime(t.submitted)),
    ...fact("Started", t.started ? clock(t.started, true) + " · waited " + duration(t.wait) : "not yet",
            "started", fullTime(t.started)),
    ...fact("Finished", t.finished ? clock(t.finished, true) + (t.started ? " · ran " + duration(t.run) : "")
                                   : "not yet", "finished", fullTime(t.finished)),
  ];
}

async function refreshDetail() {
  const id = state.selected;
  if (!id) { $("detail").hidden = true; return; }
  // The job's status comes with its units, workers and log (/detail): one request a refresh.
  let detail;
  try {
    detail = await apiJson("/api/jobs/" + encodeURIComponent(id) + "/detail");
  } catch (e) {
    if (e.status === 404) { state.selected = null; $("detail").hidden = true; return; }
    throw e;
  }
  if (id !== state.selected) return;
  const job = detail.status || {};
  $("detail").hidden = false;
  $("detail").dataset.job = id;
  $("detail-title").textContent = (job.name || id) + " (" + id + ") · " + stateName(job);
  const s = stateName(job);
  $("facts").replaceChildren(
    ...fact("Image", job.width + " × " + job.height + ", tiles of " + job.tile_size),
    ...fact("Samples per pixel", job.frames_total > 0 ? "–" : job.spp_done + " of " + sppTotal(job) +
            " (mean " + Number(job.spp_mean).toFixed(1) + ")"),
    ...fact("Progress", percentOf(job).toFixed(1) + "%"),
    ...timeFacts(job),
    ...fact("Elapsed", duration(job.elapsed_seconds)),
    ...fact("ETA", finished(job) ? "–" : duration(job.eta_seconds)),
    ...fact("Samples/s", rate(job.samples_per_second)),
    ...fact("Estimated relMSE", sci(job.est_rel_mse)),
    ...fact("relMSE to reference", sci(job.ref_rel_mse)),
    ...fact("Stop rule", job.stop_reason || "–"),
    ...fact("Workers on it", job.workers_busy + " of " + job.workers_total),
    ...fact("Priority", job.priority),
    ...(job.error ? fact("Error", job.error) : []),
    ...(job.storage_error ? fact("Storage", job.storage_error) : []));
  const canManage = state.session && state.session.authenticated &&
    (job.owner === state.session.key || state.session.admin);
  const open = !finished(job);
  $("pause").disabled = !canManage || !open || job.paused;
  $("resume").disabled = !canManage || !open || !job.paused;
  $("cancel").disabled = !canManage || !open;
  // Over: retry a failed or cancelled job, delete any (its folder too); offered once it is over.
  const st = STATES[job.state];
  $("retry").hidden = open;
  $("retry").disabled = !canManage || !(st === "failed" || st === "cancelled");
  $("remove").hidden = open;
  $("remove").disabled = !canManage || open;
  $("set-priority").disabled = !canManage || !open;
  $("priority").disabled = !canManage || !open;
  if (document.activeElement !== $("priority")) $("priority").value = job.priority;
  $("actions").title = canManage ? "" : "Sign in with a token of this job's key to act on it";

  // Images: the master rewrites them in the background, every few seconds while results arrive
  // and once more when the job ends; fetched again every 3 s while there may be a newer one (the
  // job runs, or ended less than 15 s ago), at once when the state changes.
  const sequence = job.frames_total > 0;
  const now = Date.now();
  if (state.shown.state !== s) { state.shown.state = s; state.shown.at = 0; }
  if (!finished(job)) state.shown.open = now;
  const fresh = !state.shown.at ||
    (state.shown.open !== undefined && now - state.shown.open < 15000);
  if (fresh && now - (state.shown.at || 0) >= 3000) {
    state.shown.at = now;
    const base = "/api/jobs/" + encodeURIComponent(id);
    if (sequence) {
      await loadImage($("preview"), id, base + "/contact.png");
      $("preview").alt = "contact sheet of the finished frames";
    } else {
      await loadImage($("preview"), id, base + "/image.png");
      await loadErrorRecord(id, base + "/error.csv");
      $("preview").alt = "the job's current image";
    }
    if (id !== state.selected) return;  // another job was selected meanwhile
    $("preview").dataset.version = String(++state.loads);
  }
  const target = targetError(job);
  if (!sequence && target !== state.plot.target) { state.plot.target = target; drawErrorPlot(); }
  $("error-box").hidden = sequence;
  $("detail-body").classList.toggle("sequence", sequence);
  $("preview").previousElementSibling.textContent = sequence ? "Contact sheet" : "Current image";
  $("frames-box").hidden = !sequence;
  if (sequence) drawFrames(job.frames || []);
  await showJobDetail(id, detail, sequence);
}

// ---- actions ----------------------------------------------------------------------------------

async function act(path, body) {
  const id = state.selected;
  if (!id) return;
  try {
    const options = { method: "POST" };
    if (body) {
      options.body = JSON.stringify(body);
      options.headers = { "Content-Type": "application/json" };
    }
    await apiJson("/api/jobs/" + encodeURIComponent(id) + "/" + path, options);
    say("job " + id + ": " + path + " done");
  } catch (e) {
    say("job " + id + ": " + path + " refused: " + e.message, true);
  }
  refresh();
}

// ---- session ----------------------------------------------------------------------------------

async function loadSession() {
  try {
    state.session = await apiJson("/api/session");
  } catch (e) {
    if (e.status === 401 && state.token) {
      say("sign-in refused: " + e.message, true);
      state.token = "";
      localStorage.removeItem("rayfarm-token");
      state.session = await apiJson("/api/session");
    } else {
      throw e;
    }
  }
  const who = $("who");
  if (state.session.authenticated) {
    who.textContent = state.session.key ? "key " + state.session.key + (state.session.admin ? " (admin)" : "")
                                        : "signed in";
    who.className = "badge signed";
  } else {
    who.textContent = "read-only";
    who.className = "badge";
  }
  $("token").hidden = state.session.authenticated;
  $("signin-button").hidden = state.session.authenticated;
  $("signout").hidden = !state.session.authenticated;
}

// ---- the loop ---------------------------------------------------------------------------------

async function refresh() {
  if (state.busy) return;
  state.busy = true;
  try {
    const [jobs, workers] = await Promise.all([apiJson("/api/jobs"), apiJson("/api/workers")]);
    drawJobs(jobs);
    drawWorkers(workers);
    await refreshDetail();
    if ($("message").dataset.lost) say("");
  } catch (e) {
    if (e.status === 401) {
      // A token revoked meanwhile, or reads that need one: the session says which.
      try { await loadSession(); } catch (e2) { /* said below */ }
      say(e.message, true, true);
    } else {
      say("cannot reach the master: " + e.message, true, true);
    }
  } finally {
    state.busy = false;
  }
}

window.addEventListener("DOMContentLoaded", async () => {
  $("signin").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    state.token = $("token").value.trim();
    $("token").value = "";
    say("");
    if (state.token) localStorage.setItem("rayfarm-token", state.token);
    await loadSession();
    refresh();
  });
  $("signout").addEventListener("click", async () => {
    say("");
    state.token = "";
    localStorage.removeItem("rayfarm-token");
    await loadSession();
    refresh();
  });
  $("pause").addEventListener("click", () => act("pause"));
  $("resume").addEventListener("click", () => act("resume"));
  $("cancel").addEventListener("click", () => {
    if (confirm("Cancel job " + state.selected + "? Its samples so far are kept, no more are rendered.")) act("cancel");
  });
  $("job-filter").addEventListener("input", () => { if (state.lastJobs) drawJobs(state.lastJobs); });
  for (const th of $("jobs").querySelectorAll("th[data-sort]")) {
    th.addEventListener("click", () => {
      const key = th.dataset.sort;
      state.sort = { key, ascending: state.sort.key === key ? !state.sort.ascending : true };
      if (state.lastJobs) drawJobs(state.lastJobs);
    });
  }
  $("retry").addEventListener("click", () => act("retry"));
  $("remove").addEventListener("click", () => {
    if (confirm("Delete job " + state.selected + " and its files (image, record, error record)? " +
                "This cannot be undone.")) act("remove");
  });
  $("set-priority").addEventListener("click", () =>
    act("priority", { priority: parseInt($("priority").value, 10) }));
  watchErrorPlot();
  watchFrames();
  watchWorkers();
  try { await loadSession(); } catch (e) { say("cannot reach the master: " + e.message, true); }
  refresh();
  setInterval(refresh, 1000);
});
