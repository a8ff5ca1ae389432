// rayfarm's dashboard, the error plot (a part of the page's script: master/CMakeLists.txt joins
// dashboard.js, error_plot.js, job_detail.js and workers.js into the one /dashboard.js it serves).
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

// The plot is drawn to its box's size: again when the box changes size.
function watchErrorPlot() {
  let plotWidth = 0;
  new ResizeObserver(() => {
    const w = $("error-plot").clientWidth;
    if (w && w !== plotWidth) { plotWidth = w; drawErrorPlot(); }
  }).observe($("error-plot"));
  drawErrorPlot();
}
