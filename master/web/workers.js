// rayfarm's dashboard, the workers (a part of the page's script, after dashboard.js): who is
// connected, what each renders, and its control: a worker is enabled, draining (finishes the units
// it holds, takes no new ones; drained once it holds none) or disabled (its units went back to the
// queue). Its key's owner (the client key of the same name) or an admin drains, disables and
// enables it: the buttons show where the master says this token may (`can_manage`).

function workerState(w) {
  const units = (w.units || []).length;
  if (w.control === 'disabled' || w.control === 'drained') return w.control;
  // The master says "drained" once the worker holds no unit of any job, also of jobs hidden here.
  if (w.control === 'draining') return 'draining';
  return units ? "busy" : "idle";
}

const WORKER_STATE_CLASS = { busy: "running", idle: "", draining: "paused", drained: "paused",
                             disabled: "failed" };
const WORKER_STATE_TIP = {
  busy: "rendering", idle: "waiting for work",
  draining: "drained: finishes the units it holds, takes no new ones",
  drained: "drained: holds no unit, takes no new ones until enabled",
  disabled: "disabled: takes no units until enabled",
};

// The buttons that mean something in the worker's state, where this token may use them.
function workerButtons(w) {
  if (!w.can_manage) return [];
  const control = w.control || "enabled";
  const button = (action, label, danger) => el("button", {
    type: "button", class: danger ? "danger" : "", "data-action": action, "data-worker": w.id,
    "data-name": w.name, "data-units": (w.units || []).length, title: label + " worker " + w.name }, label);
  const out = [];
  if (control === "enabled") out.push(button("drain", "Drain"));
  if (control === 'enabled' || control === 'draining' || control === 'drained') {
    out.push(button('disable', 'Disable', true));
  }
  if (control !== "enabled") out.push(button("enable", "Enable"));
  return out;
}

function drawWorkers(list) {
  const workers = list.workers || [];
  const manage = workers.some((w) => w.can_manage);
  const rows = workers.map((w) => {
    const s = workerState(w);
    const units = w.units || [];
    return el("tr", { "data-worker": w.id, "data-state": s, "data-control": w.control || "enabled" },
      el("td", { class: "text", title: w.name }, w.name),
      el("td", { class: "text", title: w.key_name || "" }, w.key_name || "–"),
      el("td", { title: WORKER_STATE_TIP[s] }, el("span", { class: "state " + WORKER_STATE_CLASS[s] }, s)),
      el("td", { class: "num" }, w.threads),
      el("td", { class: "text units", title: units.join("\n") },
         units.length ? units[0] + (units.length > 1 ? " +" + (units.length - 1) : "") : "–"),
      el("td", { class: "num" }, w.units_done),
      el("td", { class: "num" }, rate(w.samples_per_second)),
      el("td", { class: "num" }, duration(w.last_seen_seconds) + " ago"),
      el("td", { class: "manage" }, el("div", { class: "row-actions" }, ...workerButtons(w))));
  });
  $("workers").querySelector("tbody").replaceChildren(...rows);
  // The control column only where some worker's buttons show.
  $("workers").classList.toggle("manage", manage);
  $("no-workers").hidden = workers.length > 0;
  $("worker-count").textContent = workers.length ? "(" + workers.length + ")" : "";
}

const WORKER_ACTIONS = {
  drain: { done: "draining: it finishes the units it holds and takes no new ones",
           ask: (name, units) => "Drain worker " + name + "? It finishes the " + units +
             " unit(s) it holds and takes no new ones until enabled." },
  disable: { done: "disabled",
             ask: (name, units) => "Disable worker " + name + "? The " + units + " unit(s) it " +
               "holds go back to the queue now, and it takes no new ones until enabled." },
  enable: { done: "enabled: it takes work again" },
};

async function workerAct(id, name, action) {
  try {
    const reply = await apiJson("/api/workers/" + encodeURIComponent(id) + "/" + action,
                                { method: "POST", body: "" });
    const requeued = Number(reply.units_requeued || 0);
    say("worker " + name + ": " + WORKER_ACTIONS[action].done +
        (action === "disable" ? " (" + requeued + " unit" + (requeued === 1 ? "" : "s") +
                                " back in the queue)" : ""));
  } catch (e) {
    say("worker " + name + ": " + action + " refused: " + e.message, true);
  }
  refresh();
}

// One listener for the table's buttons: its rows are drawn again every second.
function watchWorkers() {
  $("workers").querySelector("tbody").addEventListener("click", (ev) => {
    const b = ev.target.closest("button[data-action]");
    if (!b || b.disabled) return;
    const { action, worker, name, units } = b.dataset;
    const ask = WORKER_ACTIONS[action].ask;
    if (ask && !confirm(ask(name, units))) return;
    workerAct(worker, name, action);
  });
}
