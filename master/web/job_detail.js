// rayfarm's dashboard, the selected job's detail (a part of the page's script, after dashboard.js):
// its units (those leased now, those that failed or were handed out again, the latest done), what
// each worker rendered of it, and its log, from /api/jobs/ID/detail; for a sequence, its frames,
// one of which can be selected for that frame's units and log.

// ---- frames -----------------------------------------------------------------------------------

function drawFrames(frames) {
  if (state.frame && !frames.some((f) => f.job_id === state.frame)) state.frame = null;
  const tiles = frames.map((f) => {
    const s = stateName(f);
    const done = s === "done";
    const box = el("button", { type: "button", class: "frame", "data-frame": f.frame,
                               "data-job": f.job_id, "data-state": s,
                               title: "frame " + f.frame + " (" + f.job_id + "): " + s });
    if (f.job_id === state.frame) box.classList.add("selected");
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
    box.append(el("div", { class: "frame-caption" }, f.frame + " ",
                  el("span", { class: "state " + s }, s === "running" ? Number(f.percent).toFixed(0) + "%" : s)));
    return box;
  });
  $("frames").replaceChildren(...tiles);
}

// A click on a frame shows its units and log below (again: the whole sequence's).
function watchFrames() {
  $("frames").addEventListener("click", (ev) => {
    const tile = ev.target.closest(".frame");
    if (!tile) return;
    state.frame = state.frame === tile.dataset.job ? null : tile.dataset.job;
    for (const t of $("frames").querySelectorAll(".frame")) {
      t.classList.toggle("selected", t.dataset.job === state.frame);
    }
    refreshDetail();
  });
  $("frame-close").addEventListener("click", () => {
    state.frame = null;
    for (const t of $("frames").querySelectorAll(".frame.selected")) t.classList.remove("selected");
    refreshDetail();
  });
}

// ---- the detail -------------------------------------------------------------------------------

function clearJobDetail() {
  $("job-detail").hidden = true;
  delete $("job-detail").dataset.job;
  $("units").querySelector("tbody").replaceChildren();
  $("shares").querySelector("tbody").replaceChildren();
  $("job-log").replaceChildren();
  delete $("job-log").dataset.drawn;
}

// Draws `detail` (the selected job's), or for a sequence whose frame is selected, that frame's.
async function showJobDetail(id, detail, sequence) {
  if (!sequence) state.frame = null;
  const frame = state.frame;
  if (frame) {
    try {
      detail = await apiJson("/api/jobs/" + encodeURIComponent(frame) + "/detail");
    } catch (e) {
      if (e.status !== 404) throw e;
      state.frame = null;  // gone meanwhile (the sequence was removed)
      return;
    }
    if (id !== state.selected || frame !== state.frame) return;  // another was chosen meanwhile
  }
  const job = detail.status || {};
  $("job-detail").hidden = false;
  $("job-detail").dataset.job = frame || id;
  $("frame-head").hidden = !frame;
  $("frame-facts").hidden = !frame;
  if (frame) {
    $("frame-title").textContent = "Frame " + job.frame + " (" + frame + ") · " + stateName(job);
    $("frame-facts").replaceChildren(
      ...fact("State", stateName(job), "state"),
      ...fact("Progress", percentOf(job).toFixed(1) + "%"),
      ...fact("Samples per pixel", job.spp_done + " of " + sppTotal(job)),
      ...timeFacts(job));
  }
  drawUnits(detail, job, sequence && !frame);
  drawShares(detail.workers || [], finished(job), Boolean(job.sequence));
  drawLog(detail.log || [], Number(detail.log_left_out || 0), Boolean(job.sequence));
}

const UNIT_STATES = { rendering: "running", queued: "queued", done: "done" };

// A worker as the master names it in a job's detail ("worker w1 (00a1b2c3d4)": its name and
// connection), without the word "worker" in a column of workers.
function workerLabel(name) { return String(name || "").replace(/^worker /, ""); }

function tileText(t) {
  if (!t) return "–";
  return (t.x0 || 0) + "–" + (t.x1 || 0) + " × " + (t.y0 || 0) + "–" + (t.y1 || 0);
}

function unitRow(u) {
  const retries = Math.max(0, (u.leases || 0) - 1);
  const t = u.tile || {};
  const workers = (u.workers || []).map(workerLabel).join(", ");
  const tr = el("tr", { "data-unit": u.unit_id, "data-state": u.state },
    el("td", { class: "num" }, u.unit_id),
    el("td", { title: "pixels x " + (t.x0 || 0) + " to " + (t.x1 || 0) + ", y " + (t.y0 || 0) + " to " +
                      (t.y1 || 0) + " (" + ((t.x1 || 0) - (t.x0 || 0)) + " × " + ((t.y1 || 0) - (t.y0 || 0)) + ")" },
       tileText(u.tile)),
    el("td", { title: "samples " + u.sample_begin + " up to " + u.sample_end + " of each pixel" },
       (u.sample_begin || 0) + "–" + (u.sample_end || 0)),
    el("td", {}, el("span", { class: "state " + (UNIT_STATES[u.state] || "") }, u.state || "–")),
    el("td", { class: "text", title: workers }, workers || "–"),
    el("td", { class: "num", title: u.state === "rendering" ? "since its lease" : "its render time" },
       u.state === "queued" ? "–" : duration(u.seconds)),
    el("td", { class: "num" + (retries ? " warn" : ""), title: (u.leases || 0) + " lease(s)" }, retries),
    el("td", { class: "text" + (u.error ? " unit-error" : ""), title: u.error || "" }, u.error || "–"));
  return tr;
}

function chip(key, count, label) {
  return el("span", { class: "chip" + (count > 0 && key !== "done" ? " " + key : ""), "data-count": key },
            el("b", {}, count), " " + label);
}

function drawUnits(detail, job, sequence) {
  const units = detail.units || [];
  const rendering = units.filter((u) => u.state === "rendering").length;
  const leftOut = Number(detail.units_left_out || 0);
  $("units").querySelector("tbody").replaceChildren(...units.map(unitRow));
  $("units-wrap").hidden = units.length === 0;
  $("unit-counts").textContent = units.length
    ? "(" + units.length + " listed" + (leftOut ? ", " + leftOut + " more done" : "") + ")" : "";
  $("unit-summary").hidden = sequence;
  $("unit-summary").replaceChildren(
    chip("rendering", rendering, "rendering"),
    chip("queued", Number(detail.units_queued || 0), "queued"),
    chip("retried", Number(detail.units_retried || 0), "retried"),
    chip("failed", Number(detail.units_failed || 0), "failed"),
    chip("done", Number(job.units_done || 0), "of " + Number(job.units_total || 0) + " done"));
  const empty = $("no-units");
  empty.hidden = units.length > 0;
  empty.textContent = sequence ? "A sequence's units are its frames': click a frame above."
    : finished(job) ? "It is over: the master keeps a job's units only while it runs."
    : "No unit of it handed out yet.";
}

function drawShares(shares, over, frame) {
  const total = shares.reduce((n, w) => n + Number(w.units_done || 0), 0);
  const rows = [...shares].sort((a, b) => Number(b.units_done) - Number(a.units_done)).map((w) => {
    const pct = total ? 100 * Number(w.units_done || 0) / total : 0;
    const tr = el("tr", { "data-worker": w.worker },
      el("td", { class: "text", title: w.worker }, workerLabel(w.worker)),
      el("td", { class: "num" }, w.units_done),
      el("td", { class: "num" }, duration(w.render_seconds)),
      el("td", { class: "num" + (w.failures ? " warn" : "") }, w.failures || 0),
      el("td", {}, el("span", { class: "bar" }, el("div", {})),
         el("span", { class: "percent" }, pct.toFixed(0) + "%")));
    tr.querySelector(".bar > div").style.width = pct.toFixed(1) + "%";
    return tr;
  });
  $("shares").querySelector("tbody").replaceChildren(...rows);
  $("shares-wrap").hidden = rows.length === 0;
  $("no-shares").hidden = rows.length > 0;
  $("no-shares").textContent = !over ? "No unit of it rendered yet."
    : "It is over: the master keeps the workers' shares only while a job runs" +
      (frame ? "." : " (its log's last line names them).");
}

// The log, oldest first, kept scrolled to its newest line unless the reader scrolled up.
function drawLog(lines, leftOut, frame) {
  const box = $("job-log");
  const last = lines[lines.length - 1];
  const key = lines.length + "/" + leftOut + "/" + (last ? last.unix_ms + last.text : "");
  if (box.dataset.drawn === key) return;
  const atEnd = !box.dataset.drawn || box.scrollTop + box.clientHeight >= box.scrollHeight - 4;
  box.dataset.drawn = key;
  const items = lines.map((l) => {
    const ms = unixMs(l.unix_ms);
    return el("li", { class: "log-line " + (l.level || "info"), "data-level": l.level || "info" },
      el("time", { title: fullTime(ms) }, clock(ms, true)),
      el("span", { class: "level" }, l.level || "info"),
      el("span", { class: "log-text" }, l.text || ""));
  });
  if (leftOut > 0) items.unshift(el("li", { class: "log-more" }, leftOut + " earlier lines left out"));
  if (!items.length) {
    // A sequence's frames log only what is out of the ordinary; their times say the rest.
    items.push(el("li", { class: "log-more" }, frame
      ? "nothing out of the ordinary: a frame logs its failures and errors only" : "nothing logged yet"));
  }
  box.replaceChildren(...items);
  $("log-count").textContent = lines.length ? "(" + (lines.length + leftOut) + " lines)" : "";
  if (atEnd) box.scrollTop = box.scrollHeight;
}
