// rayfarm's dashboard: polls the master's JSON API (docs/farm.md, "The dashboard") once a second
// and draws jobs, the selected job's image, error plot and frames, and the workers. Actions send
// the token from `rayfarm token` as a bearer token; without one the page is read-only.
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

// ---- workers ----------------------------------------------------------------------------------

function drawWorkers(list) {
  const rows = list.workers.map((w) => el("tr", { "data-worker": w.id },
    el("td", { class: "text", title: w.name }, w.name),
    el("td", { class: "text", title: w.key_name || "" }, w.key_name || "–"),
    el("td", {}, el("span", { class: "state " + (w.units.length ? "running" : "") },
                    w.units.length ? "busy" : "idle")),
    el("td", { class: "num" }, w.threads),
    el("td", { class: "text", title: w.units.join("\n") },
       w.units.length ? w.units[0] + (w.units.length > 1 ? " +" + (w.units.length - 1) : "") : "–"),
    el("td", { class: "num" }, w.units_done),
    el("td", { class: "num" }, rate(w.samples_per_second)),
    el("td", { class: "num" }, duration(w.last_seen_seconds) + " ago")));
  $("workers").querySelector("tbody").replaceChildren(...rows);
  $("no-workers").hidden = list.workers.length > 0;
  $("worker-count").textContent = list.workers.length ? "(" + list.workers.length + ")" : "";
}

// ---- the selected job -------------------------------------------------------------------------

function select(id) {
  if (id !== state.selected) {
    clearImage($("preview"));
    state.plot = { rows: [], target: 0 };
    drawErrorPlot();
    for (const url of state.thumbs.values()) if (url) URL.revokeObjectURL(url);
    state.thumbs.clear();
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

function fact(name, value) { return [el("div", { class: "fact" }, el("dt", {}, name), el("dd", {}, value))]; }

async function refreshDetail() {
  const id = state.selected;
  if (!id) { $("detail").hidden = true; return; }
  let job;
  try {
    job = await apiJson("/api/jobs/" + encodeURIComponent(id));
  } catch (e) {
    if (e.status === 404) { state.selected = null; $("detail").hidden = true; return; }
    throw e;
  }
  if (id !== state.selected) return;
  $("detail").hidden = false;
  $("detail").dataset.job = id;
  $("detail-title").textContent = (job.name || id) + " (" + id + ") · " + stateName(job);
  const s = stateName(job);
  $("facts").replaceChildren(
    ...fact("Image", job.width + " × " + job.height + ", tiles of " + job.tile_size),
    ...fact("Samples per pixel", job.frames_total > 0 ? "–" : job.spp_done + " of " + sppTotal(job) +
            " (mean " + Number(job.spp_mean).toFixed(1) + ")"),
    ...fact("Progress", percentOf(job).toFixed(1) + "%"),
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
}

// ---- the error plot ---------------------------------------------------------------------------
// The job's error record (error.csv: time_s, spp, ..., est_rel_mse, ..., ref_rel_mse, ...) drawn
// as an inline SVG, log-log: the estimated relMSE, the relMSE measured against a reference when
// the job has one, and the target error as a horizontal line when the job has one.

// The job's target relMSE (its status's target_error), or 0 when it has none.
function targetError(job) {
  const t = Number(job.target_error || 0);
  return t > 0 && isFinite(t) ? t : 0;
}

function parseErrorCsv(text) {
  const lines = text.split(/\r?\n/).filter((l) => l.trim());
  if (!lines.length) return [];
  const head = lines[0].split(",").map((c) => c.trim());
  const col = (name) => head.indexOf(name);
  const [t, est, ref] = [col("time_s"), col("est_rel_mse"), col("ref_rel_mse")];
  if (t < 0 || est < 0) return [];
  return lines.slice(1).map((l) => {
    const c = l.split(",");
    const num = (i) => (i >= 0 && c[i] !== undefined && c[i].trim() !== "" ? Number(c[i]) : NaN);
    return { t: num(t), est: num(est), ref: num(ref) };
  }).filter((r) => r.t > 0 && isFinite(r.t));
}

async function loadErrorRecord(id, path) {
  let rows = [];
  try {
    rows = parseErrorCsv(await (await api(path)).text());
  } catch (e) { /* not written yet */ }
  if (id !== state.selected) return;
  state.plot.rows = rows;
  drawErrorPlot();
}

const SUPERSCRIPT = { "-": "⁻", 0: "⁰", 1: "¹", 2: "²", 3: "³", 4: "⁴", 5: "⁵", 6: "⁶", 7: "⁷", 8: "⁸", 9: "⁹" };
function powerOfTen(e) { return "10" + String(e).split("").map((c) => SUPERSCRIPT[c]).join(""); }
function splitTen(x) {
  const e = Math.floor(Math.log10(x) + 1e-9);
  return [Math.round(x / Math.pow(10, e)), e];
}
function seconds(x) {
  if (x >= 1e5 || x < 1e-3) { const [m, e] = splitTen(x); return (m === 1 ? "" : m + "×") + powerOfTen(e); }
  return String(Number(x.toPrecision(2)));
}
function relMse(x) { const [m, e] = splitTen(x); return (m === 1 ? "" : m + "×") + powerOfTen(e); }

// Ticks of a log axis over [lo, hi]: 1, 2, 5 (or 1..9 on a short axis) times the powers of ten,
// only the powers of ten on a long one.
function logTicks(lo, hi) {
  const span = Math.log10(hi / lo);
  const steps = span > 3 ? [1] : span > 1.2 ? [1, 2, 5] : [1, 2, 3, 4, 5, 6, 7, 8, 9];
  const every = span > 8 ? Math.ceil(span / 6) : 1;
  const ticks = [];
  for (let e = Math.floor(Math.log10(lo)) - 1; e <= Math.ceil(Math.log10(hi)); ++e) {
    if (steps.length === 1 && e % every) continue;
    for (const m of steps) {
      const v = m * Math.pow(10, e);
      if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) ticks.push(v);
    }
  }
  return ticks;
}

// A range [lo, hi] around `values` (all > 0), a little wider than they are, in log space.
function logRange(values) {
  let lo = Math.min(...values), hi = Math.max(...values);
  if (hi / lo < 1.5) { const mid = Math.sqrt(lo * hi); lo = mid / 1.6; hi = mid * 1.6; }
  const pad = Math.pow(hi / lo, 0.05);
  return [lo / pad, hi * pad];
}

function svgEl(tag, attrs, text) {
  const e = document.createElementNS("http://www.w3.org/2000/svg", tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function drawErrorPlot() {
  const box = $("error-plot");
  const W = Math.max(300, Math.round(box.clientWidth)), H = Math.max(240, Math.round(box.clientHeight));
  const svg = svgEl("svg", { viewBox: `0 0 ${W} ${H}`, width: W, height: H, id: "error-plot-svg" });
  const { rows, target } = state.plot;
  const est = rows.filter((r) => r.est > 0 && isFinite(r.est));
  const ref = rows.filter((r) => r.ref > 0 && isFinite(r.ref));
  box.dataset.points = String(est.length);
  box.dataset.target = target ? String(target) : "";
  // The legend above the plot, in as many rows as its entries need.
  const now = est[est.length - 1];
  const entries = est.length ? [["series-est", "estimated relMSE (now " + sci(now.est) + " at " + duration(now.t) + ")"]] : [];
  if (ref.length) entries.push(["series-ref", "measured against the reference"]);
  if (target && est.length) entries.push(["target", "target error " + sci(target)]);
  const m = { left: 78, right: 18, top: 30, bottom: 48 };
  const placed = [];
  let lx = m.left, ly = 14;
  for (const [cls, name] of entries) {
    const w = 28 + name.length * 6.6 + 20;
    if (lx > m.left && lx + w > W - m.right) { lx = m.left; ly += 18; }
    placed.push([cls, name, lx, ly]);
    lx += w;
  }
  m.top = ly + 16;
  const pw = W - m.left - m.right, ph = H - m.top - m.bottom;
  // Axis labels, always there.
  svg.append(svgEl("text", { class: "label axis-label x-label", x: m.left + pw / 2, y: H - 8,
                             "text-anchor": "middle" }, "time (s)"));
  svg.append(svgEl("text", { class: "label axis-label y-label", "text-anchor": "middle",
                             transform: `translate(16 ${m.top + ph / 2}) rotate(-90)` },
                   "relative MSE"));
  svg.append(svgEl("rect", { class: "axis", x: m.left, y: m.top, width: pw, height: ph }));
  if (!est.length) {
    svg.append(svgEl("text", { class: "none", x: m.left + pw / 2, y: m.top + ph / 2,
                               "text-anchor": "middle" }, "no error record yet"));
    box.replaceChildren(svg);
    return;
  }
  const times = est.concat(ref).map((r) => r.t);
  const errors = est.map((r) => r.est).concat(ref.map((r) => r.ref), target ? [target] : []);
  const [x0, x1] = logRange(times), [y0, y1] = logRange(errors);
  const X = (v) => m.left + pw * Math.log(v / x0) / Math.log(x1 / x0);
  const Y = (v) => m.top + ph * (1 - Math.log(v / y0) / Math.log(y1 / y0));
  // Grid lines and tick labels; a label closer to the last one than a label's size is left out.
  let last = -Infinity;
  for (const v of logTicks(x0, x1)) {
    const x = X(v);
    svg.append(svgEl("line", { class: "grid", x1: x, x2: x, y1: m.top, y2: m.top + ph }));
    svg.append(svgEl("line", { class: "axis", x1: x, x2: x, y1: m.top + ph, y2: m.top + ph + 5 }));
    const label = seconds(v);
    if (x - last < label.length * 7 + 10) continue;
    last = x;
    svg.append(svgEl("text", { class: "tick x-tick", x, y: m.top + ph + 19, "text-anchor": "middle" }, label));
  }
  last = Infinity;
  for (const v of logTicks(y0, y1)) {
    const y = Y(v);
    svg.append(svgEl("line", { class: "grid", x1: m.left, x2: m.left + pw, y1: y, y2: y }));
    svg.append(svgEl("line", { class: "axis", x1: m.left - 5, x2: m.left, y1: y, y2: y }));
    if (last - y < 16) continue;
    last = y;
    svg.append(svgEl("text", { class: "tick y-tick", x: m.left - 8, y: y + 4, "text-anchor": "end" }, relMse(v)));
  }
  if (target) {
    const y = Y(target);
    svg.append(svgEl("line", { class: "target", x1: m.left, x2: m.left + pw, y1: y, y2: y }));
    // Labelled at the left end, above the line: the curves fall towards it from there, and reach
    // it (if ever) at the right.
    svg.append(svgEl("text", { class: "target-label", x: m.left + 8, y: y - 6 }, "target " + sci(target)));
  }
  const series = (list, key, cls, name) => {
    if (!list.length) return;
    const points = list.map((r) => X(r.t).toFixed(1) + "," + Y(r[key]).toFixed(1)).join(" ");
    const line = svgEl("polyline", { class: "series-" + cls, points });
    line.append(svgEl("title", {}, name));
    svg.append(line);
    const endpoint = list[list.length - 1];
    svg.append(svgEl("circle", { class: "dot-" + cls, cx: X(endpoint.t), cy: Y(endpoint[key]), r: 3.5 }));
  };
  series(ref, "ref", "ref", "measured against the reference");
  series(est, "est", "est", "estimated relMSE");
  for (const [cls, name, x, y] of placed) {
    svg.append(svgEl("line", { class: cls, x1: x, x2: x + 22, y1: y, y2: y }));
    svg.append(svgEl("text", { class: "legend", x: x + 28, y: y + 4 }, name));
  }
  box.replaceChildren(svg);
}

function drawFrames(frames) {
  const tiles = frames.map((f) => {
    const done = STATES[f.state] === "done";
    const box = el("div", { class: "frame", "data-frame": f.frame });
    if (done && state.thumbs.get(f.job_id)) {
      box.append(el("img", { src: state.thumbs.get(f.job_id), alt: "frame " + f.frame }));
    } else {
      box.append(el("div", { class: "pending" }));
      // One fetch per finished frame (a finished frame's image does not change), a few at a time.
      const loading = [...state.thumbs.values()].filter((u) => u === null).length;
      if (done && !state.thumbs.has(f.job_id) && loading < 4) {
        state.thumbs.set(f.job_id, null);
        api("/api/jobs/" + encodeURIComponent(f.job_id) + "/image.png")
          .then((r) => r.blob())
          .then((b) => state.thumbs.set(f.job_id, URL.createObjectURL(b)))
          .catch(() => state.thumbs.delete(f.job_id));
      }
    }
    box.append(el("div", {}, f.frame + " · " +
      (done ? "done" : STATES[f.state] === "running" ? Number(f.percent).toFixed(0) + "%" : STATES[f.state])));
    return box;
  });
  $("frames").replaceChildren(...tiles);
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
  // The plot is drawn to its box's size: again when the box changes size.
  let plotWidth = 0;
  new ResizeObserver(() => {
    const w = $("error-plot").clientWidth;
    if (w && w !== plotWidth) { plotWidth = w; drawErrorPlot(); }
  }).observe($("error-plot"));
  drawErrorPlot();
  try { await loadSession(); } catch (e) { say("cannot reach the master: " + e.message, true); }
  refresh();
  setInterval(refresh, 1000);
});
