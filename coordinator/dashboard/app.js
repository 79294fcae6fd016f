// The Tessera dashboard: polls the coordinator's JSON API every second and keeps the page's
// tables up to date in place (rows are keyed by job, frame and worker, so that an input
// being typed in survives a refresh). No framework, no build step; see docs/dashboard.md.
"use strict";

const POLL_MS = 1000;
const LOG_LIMIT = 200;

const view = {
  job: null,      // the selected job's id
  frame: null,    // the frame chosen for the preview (null: the job's current frame)
  previewKey: "", // what the preview <img> shows: job/frame/tasks done/state
  polling: false,
};

// --- helpers ---------------------------------------------------------------------------

async function api(path, options = {}) {
  const response = await fetch(path, { credentials: "same-origin", ...options });
  if (response.status === 401) {
    window.location.assign("/login");
    throw new Error("not logged in");
  }
  let body = null;
  try {
    body = await response.json();
  } catch (e) {
    body = null;
  }
  if (!response.ok) {
    throw new Error(body && body.error ? body.error : `${response.status} ${response.statusText}`);
  }
  return body;
}

function post(path, body) {
  return api(path, {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify(body || {}),
  });
}

function el(tag, className, text) {
  const node = document.createElement(tag);
  if (className) node.className = className;
  if (text !== undefined) node.textContent = text;
  return node;
}

function setText(node, text) {
  const value = String(text);
  if (node.textContent !== value) node.textContent = value;
}

// The row of `tbody` keyed `key` in attribute `attr`, made by `make` when missing.
function keyedRow(tbody, attr, key, make) {
  let row = tbody.querySelector(`tr[${attr}="${CSS.escape(String(key))}"]`);
  if (!row) {
    row = make();
    row.setAttribute(attr, key);
  }
  return row;
}

// Puts `rows` in `tbody` in that order and removes the others.
function placeRows(tbody, rows) {
  rows.forEach((row, i) => {
    if (tbody.children[i] !== row) tbody.insertBefore(row, tbody.children[i] || null);
  });
  while (tbody.children.length > rows.length) tbody.lastElementChild.remove();
}

function percent(done, total) {
  return total > 0 ? Math.floor((100 * done) / total) : 0;
}

function rate(value) {
  if (!value) return "–";
  const units = [[1e9, "G"], [1e6, "M"], [1e3, "k"]];
  for (const [scale, unit] of units) {
    if (value >= scale) return `${(value / scale).toFixed(1)} ${unit}`;
  }
  return value.toFixed(0);
}

function age(nowMs, thenMs) {
  if (!thenMs) return "never";
  const s = Math.max(0, Math.round((nowMs - thenMs) / 1000));
  if (s < 120) return `${s} s ago`;
  if (s < 7200) return `${Math.round(s / 60)} min ago`;
  return `${Math.round(s / 3600)} h ago`;
}

function clock(ms) {
  return new Date(ms).toLocaleTimeString();
}

function showMessage(text) {
  const message = document.getElementById("message");
  message.hidden = !text;
  setText(message, text || "");
}

async function act(promise) {
  try {
    await promise;
    showMessage("");
  } catch (e) {
    showMessage(e.message);
  }
  refresh();
}

function progressBar() {
  const bar = el("div", "progress");
  bar.append(el("div", "bar"), el("span", "label"));
  return bar;
}

function setProgress(bar, done, total) {
  const p = percent(done, total);
  bar.firstChild.style.width = `${p}%`;
  setText(bar.lastChild, `${p} % (${done}/${total})`);
  bar.dataset.done = done;
}

const FINISHED = new Set(["DONE", "FAILED", "CANCELLED"]);

// --- jobs ------------------------------------------------------------------------------

function makeJobRow(job) {
  const row = el("tr", "job");
  const priority = el("td", "priority");
  const input = el("input", "priority-input");
  input.type = "number";
  input.step = "1";
  const set = el("button", "set-priority", "Set");
  set.title = "Set the job's priority (higher runs first)";
  set.addEventListener("click", (event) => {
    event.stopPropagation();
    const value = Number.parseInt(input.value, 10);
    if (Number.isNaN(value)) return showMessage("The priority is a whole number.");
    act(post(`/api/jobs/${encodeURIComponent(job.job_id)}/priority`, { priority: value }));
  });
  input.addEventListener("click", (event) => event.stopPropagation());
  input.addEventListener("keydown", (event) => {
    if (event.key === "Enter") set.click();
  });
  priority.append(input, set);

  const actions = el("td", "actions");
  const cancel = el("button", "cancel", "Cancel");
  cancel.addEventListener("click", (event) => {
    event.stopPropagation();
    act(post(`/api/jobs/${encodeURIComponent(job.job_id)}/cancel`));
  });
  const retry = el("button", "retry", "Retry");
  retry.addEventListener("click", (event) => {
    event.stopPropagation();
    act(post(`/api/jobs/${encodeURIComponent(job.job_id)}/retry`));
  });
  actions.append(cancel, retry);

  const progress = el("td", "progress-cell");
  progress.append(progressBar());
  row.append(el("td", "id"), el("td", "name"), el("td", "state"), priority, progress,
             el("td", "stage"), actions);
  row.addEventListener("click", () => selectJob(job.job_id));
  return row;
}

function updateJobRow(row, job) {
  setText(row.querySelector(".id"), job.job_id);
  setText(row.querySelector(".name"), job.name);
  const state = row.querySelector(".state");
  setText(state, job.state);
  state.dataset.state = job.state;
  row.dataset.state = job.state;
  const input = row.querySelector(".priority-input");
  if (document.activeElement !== input) input.value = job.priority;
  setProgress(row.querySelector(".progress"), job.tasks_done, job.tasks_total);
  setText(row.querySelector(".stage"), job.stage_label);
  row.querySelector("button.cancel").disabled = FINISHED.has(job.state);
  row.querySelector("button.retry").disabled = !(job.state === "FAILED" || job.state === "CANCELLED");
  row.classList.toggle("selected", job.job_id === view.job);
}

function renderJobs(jobs) {
  const tbody = document.querySelector("#jobs tbody");
  // Newest first.
  const sorted = [...jobs].sort((a, b) => b.submitted_unix_ms - a.submitted_unix_ms ||
                                          b.job_id.localeCompare(a.job_id));
  const rows = sorted.map((job) => {
    const row = keyedRow(tbody, "data-job", job.job_id, () => makeJobRow(job));
    updateJobRow(row, job);
    return row;
  });
  placeRows(tbody, rows);
  document.getElementById("no-jobs").hidden = jobs.length > 0;
}

function selectJob(id) {
  if (view.job !== id) {
    view.job = id;
    view.frame = null;
    view.previewKey = "";
    document.getElementById("log-task").value = "";
    document.querySelector("#log tbody").replaceChildren();
  }
  refresh();
}

// --- the selected job ------------------------------------------------------------------

function renderFrames(job) {
  const tbody = document.querySelector("#frames tbody");
  const rows = job.frames.map((frame) => {
    const row = keyedRow(tbody, "data-frame", frame.frame, () => {
      const r = el("tr", "frame");
      const cell = el("td", "progress-cell");
      cell.append(progressBar());
      r.append(el("td", "number"), el("td", "state"), el("td", "stage"), el("td", "stage-tasks"),
               cell);
      r.addEventListener("click", () => {
        view.frame = frame.frame;
        refresh();
      });
      return r;
    });
    setText(row.querySelector(".number"), frame.frame);
    const state = row.querySelector(".state");
    setText(state, frame.state);
    state.dataset.state = frame.state;
    setText(row.querySelector(".stage"), frame.stage_label);
    setText(row.querySelector(".stage-tasks"), `${frame.stage_done}/${frame.stage_total}`);
    setProgress(row.querySelector(".progress"), frame.tasks_done, frame.tasks_total);
    row.classList.toggle("selected", frame.frame === previewFrame(job));
    return row;
  });
  placeRows(tbody, rows);
}

function renderFailures(job) {
  const box = document.getElementById("failures");
  const key = JSON.stringify(job.failures);
  if (box.dataset.key === key) return;
  box.dataset.key = key;
  if (job.failures.length === 0) {
    box.replaceChildren(el("p", "empty", "none"));
    return;
  }
  box.replaceChildren(...job.failures.map((f) => {
    const item = el("details", "failure");
    const summary = el("summary");
    summary.append(
      el("span", "where", `frame ${f.frame}, ${f.stage} task ${f.task_index} (task ${f.task}), ` +
                          `attempt ${f.attempt} on ${f.worker || "?"}: `),
      el("span", "error-text", f.message));
    item.append(summary);
    if (f.log_tail) item.append(el("pre", "log-tail", f.log_tail));
    const show = el("button", "show-task-log", "Task log");
    show.addEventListener("click", () => {
      document.getElementById("log-task").value = f.task;
      refresh();
    });
    item.append(show);
    return item;
  }));
}

function renderLog(entries) {
  const tbody = document.querySelector("#log tbody");
  // Newest first.
  tbody.replaceChildren(...[...entries].reverse().map((e) => {
    const row = el("tr", `log-${e.kind}`);
    const message = el("td", "log-message");
    message.append(el("span", "", e.message));
    if (e.log_tail) message.append(el("pre", "log-tail", e.log_tail));
    row.append(el("td", "", clock(e.at_unix_ms)), el("td", "kind", e.kind),
               el("td", "", e.frame >= 0 ? e.frame : ""), el("td", "", e.stage),
               el("td", "", e.task >= 0 ? e.task : ""), el("td", "", e.worker),
               el("td", "", e.attempt > 0 ? e.attempt : ""), message);
    return row;
  }));
}

function previewFrame(job) {
  const chosen = job.frames.find((f) => f.frame === view.frame);
  return chosen ? chosen.frame : job.current_frame;
}

// Reloads the preview when what it shows changed: while a frame renders, every poll that
// finds more tasks done (the query string defeats the browser's cache).
function renderPreview(job) {
  const img = document.getElementById("preview");
  const caption = document.getElementById("preview-caption");
  const number = previewFrame(job);
  const frame = job.frames.find((f) => f.frame === number);
  if (!frame) {
    img.hidden = true;
    setText(caption, "no frame");
    return;
  }
  img.hidden = false;
  const key = `${job.job_id}/${frame.frame}/${frame.tasks_done}/${frame.state}`;
  if (key !== view.previewKey) {
    view.previewKey = key;
    img.src = `/api/jobs/${encodeURIComponent(job.job_id)}/frames/${frame.frame}/preview.png` +
              `?v=${frame.tasks_done}-${frame.state}&t=${Date.now()}`;
  }
  const what = frame.state === "DONE" ? "written" :
               frame.state === "RENDERING" ? `rendering: ${frame.stage_label} ` +
                                             `${frame.stage_done}/${frame.stage_total}` :
               frame.state.toLowerCase();
  setText(caption, `frame ${frame.frame} (${what})`);
}

async function renderDetail(job) {
  const section = document.getElementById("job-detail");
  if (!job) {
    section.hidden = true;
    return;
  }
  section.hidden = false;
  setText(document.getElementById("detail-id"), job.job_id);
  setText(document.getElementById("detail-name"),
          `${job.name}: ${job.width}×${job.height}, ${job.spp} spp, ${job.state}`);
  const error = document.getElementById("detail-error");
  error.hidden = !job.error;
  setText(error, job.error);
  const problem = document.getElementById("detail-problem");
  problem.hidden = !job.farm_problem;
  setText(problem, job.farm_problem);
  renderFrames(job);
  renderFailures(job);
  renderPreview(job);
  const task = document.getElementById("log-task").value.trim();
  const query = `limit=${LOG_LIMIT}` + (task !== "" ? `&task=${encodeURIComponent(task)}` : "");
  const log = await api(`/api/jobs/${encodeURIComponent(job.job_id)}/log?${query}`);
  if (log.job_id === view.job) renderLog(log.entries);
}

// --- workers ---------------------------------------------------------------------------

function makeWorkerRow(worker) {
  const row = el("tr", "worker");
  const actions = el("td", "actions");
  const enable = el("button", "enable", "Enable");
  enable.addEventListener("click", () =>
    act(post(`/api/workers/${encodeURIComponent(worker.name)}/enable`)));
  const disable = el("button", "disable", "Disable");
  disable.title = "Finish the tasks it holds, then take no new ones";
  disable.addEventListener("click", () =>
    act(post(`/api/workers/${encodeURIComponent(worker.name)}/disable`)));
  actions.append(enable, disable);
  row.append(el("td", "name"), el("td", "state"), el("td", "current-task"), el("td", "rays"),
             el("td", "samples"), el("td", "tasks"), el("td", "heartbeat"), actions);
  return row;
}

function renderWorkers(workers, nowMs) {
  const tbody = document.querySelector("#workers tbody");
  const rows = workers.map((w) => {
    const row = keyedRow(tbody, "data-worker", w.name, () => makeWorkerRow(w));
    setText(row.querySelector(".name"), w.name);
    const state = row.querySelector(".state");
    setText(state, w.state);
    state.dataset.state = w.state;
    setText(row.querySelector(".current-task"), w.current_task || "–");
    setText(row.querySelector(".rays"), rate(w.rays_per_second));
    setText(row.querySelector(".samples"), rate(w.samples_per_second));
    setText(row.querySelector(".tasks"), `${w.tasks_done} / ${w.tasks_failed}`);
    setText(row.querySelector(".heartbeat"), age(nowMs, w.last_seen_unix_ms));
    row.querySelector("button.enable").hidden = !w.disabled;
    row.querySelector("button.disable").hidden = w.disabled;
    return row;
  });
  placeRows(tbody, rows);
  document.getElementById("no-workers").hidden = workers.length > 0;
}

// --- polling ---------------------------------------------------------------------------

async function refresh() {
  if (view.polling) return;
  view.polling = true;
  try {
    const [jobs, workers] = await Promise.all([api("/api/jobs"), api("/api/workers")]);
    renderJobs(jobs.jobs);
    renderWorkers(workers.workers, workers.now_unix_ms);
    if (view.job === null && jobs.jobs.length > 0) {
      // Show the job under way (else the newest) until the user picks one.
      const running = jobs.jobs.find((j) => j.state === "RUNNING");
      view.job = (running || jobs.jobs[jobs.jobs.length - 1]).job_id;
    }
    await renderDetail(jobs.jobs.find((j) => j.job_id === view.job));
    const status = document.getElementById("status");
    setText(status, `updated ${clock(jobs.now_unix_ms)}`);
    status.classList.remove("offline");
  } catch (e) {
    const status = document.getElementById("status");
    setText(status, `cannot reach the coordinator: ${e.message}`);
    status.classList.add("offline");
  } finally {
    view.polling = false;
  }
}

document.getElementById("log-task").addEventListener("change", refresh);
refresh();
setInterval(refresh, POLL_MS);
