// The lab's dashboard: stored runs and results, a live plot of the running experiment over
// the run's Server-Sent Events, start and stop. It uses the service's public JSON routes only.
"use strict";

// How often the run and result lists are refreshed, ms.
const REFRESH_MS = 2000;
// Most samples the live plot keeps (the newest), to bound memory on long runs.
const LIVE_MAX_SAMPLES = 200000;

const $ = (id) => document.getElementById(id);
const state = { key: sessionStorage.getItem("stand-key") || "", keyed: false, live: null };

function headers(json) {
  const h = json ? { "Content-Type": "application/json" } : {};
  if (state.key) h.Authorization = `Bearer ${state.key}`;
  return h;
}

async function getJSON(url) {
  const answer = await fetch(url, { headers: headers(false) });
  if (!answer.ok) throw new Error(`${url}: ${answer.status} ${await answer.text()}`);
  return answer.json();
}

async function post(url, body) {
  const answer = await fetch(url, { method: "POST", headers: headers(true),
    body: body === undefined ? undefined : JSON.stringify(body) });
  const data = await answer.json().catch(() => ({}));
  if (answer.status === 401) {
    $("key-box").hidden = false;
    throw new Error(`the service wants its key: ${data.detail || answer.status}`);
  }
  if (!answer.ok) throw new Error(data.detail ? JSON.stringify(data.detail) : `${answer.status}`);
  return data;
}

function note(id, text, ok) {
  $(id).textContent = text;
  $(id).className = ok ? "ok" : "error";
}

function when(seconds) {
  return seconds ? new Date(seconds * 1000).toLocaleString() : "";
}

function row(cells, onClick, id) {
  const tr = document.createElement("tr");
  tr.dataset.id = id;
  cells.forEach((text, k) => {
    const td = document.createElement("td");
    td.textContent = text;
    if (k === 0) td.className = "id";
    tr.appendChild(td);
  });
  tr.addEventListener("click", onClick);
  return tr;
}

async function refreshRuns() {
  const runs = await getJSON("/runs?limit=50");
  const body = $("runs").querySelector("tbody");
  body.replaceChildren(...runs.map((r) => row(
    [r.id.slice(0, 8), r.kind, r.origin, r.profile || (r.meta.filename || ""), r.state,
      r.samples, when(r.created_s)], () => showRun(r.id), r.id)));
  const running = runs.find((r) => r.state === "running");
  if (running && (!state.live || state.live.id !== running.id)) follow(running.id);
}

async function refreshResults() {
  const results = await getJSON("/results?limit=50");
  const body = $("results").querySelector("tbody");
  body.replaceChildren(...results.map((r) => row(
    [r.id.slice(0, 8), r.operation, when(r.created_s)], () => showResult(r.id), r.id)));
}

async function showRun(id) {
  $("run-box").hidden = false;
  $("run-id").textContent = id;
  plotColumns($("run-plot"), await getJSON(`/runs/${id}/samples?format=json`));
}

function showResult(id) {
  $("result-box").hidden = false;
  $("result-id").textContent = id;
  $("result-report").href = `/results/${id}/report`;
  $("result-frame").src = `/results/${id}/report`;
}

// Follow run `id` over its event stream and redraw the live plot on every batch of samples.
function follow(id) {
  if (state.live) state.live.source.close();
  const live = { id, columns: {}, updates: 0, source: new EventSource(`/runs/${id}/events`) };
  state.live = live;
  const canvas = $("live");
  canvas.dataset.updates = "0";
  canvas.dataset.run = id;
  live.source.addEventListener("progress", (e) => {
    const p = JSON.parse(e.data);
    $("live-state").textContent = `${id.slice(0, 8)}: ${p.state}, ${(100 * p.progress).toFixed(0)} %,`
      + ` ${p.samples} samples`;
    canvas.dataset.state = p.state;
  });
  live.source.addEventListener("samples", (e) => {
    const batch = JSON.parse(e.data).columns;
    for (const [name, values] of Object.entries(batch)) {
      const kept = (live.columns[name] || []).concat(values);
      live.columns[name] = kept.length > LIVE_MAX_SAMPLES ? kept.slice(-LIVE_MAX_SAMPLES) : kept;
    }
    plotColumns(canvas, live.columns);
    live.updates++;
    canvas.dataset.updates = String(live.updates);
  });
  live.source.addEventListener("end", (e) => {
    const end = JSON.parse(e.data);
    $("live-state").textContent = `${id.slice(0, 8)}: ${end.state}${end.message ? ": " + end.message : ""}`;
    canvas.dataset.state = end.state;
    live.source.close();
    refreshRuns().catch(() => {});
  });
}

async function start() {
  try {
    const body = { profile: $("experiment").value,
      overrides: { duration_s: Number($("duration").value), repeats: 1 } };
    const answer = await post("/runs", body);
    note("control-note", `queued ${answer.runs.length} run(s)`, true);
    follow(answer.runs[0]);
    refreshRuns().catch(() => {});
  } catch (err) {
    note("control-note", String(err.message || err), false);
  }
}

async function stop() {
  try {
    await post("/stop");
    note("control-note", "quick stop sent to every drive", true);
  } catch (err) {
    note("control-note", String(err.message || err), false);
  }
}

async function init() {
  const health = await getJSON("/health");
  state.keyed = health.auth.startsWith("bearer");
  $("health").textContent = `service ${health.status}; ${health.auth}`;
  $("key-box").hidden = !state.keyed || Boolean(state.key);
  $("key").value = state.key;
  $("key-save").addEventListener("click", () => {
    state.key = $("key").value;
    sessionStorage.setItem("stand-key", state.key);
    note("key-note", "key kept for this tab", true);
  });
  $("start").addEventListener("click", start);
  $("stop").addEventListener("click", stop);
  const profiles = await getJSON("/profiles");
  $("experiment").replaceChildren(...(profiles.experiments || []).map((name) => {
    const option = document.createElement("option");
    option.value = option.textContent = name;
    return option;
  }));
  const refresh = () => Promise.all([refreshRuns(), refreshResults()])
    .catch((err) => note("control-note", String(err.message || err), false));
  await refresh();
  setInterval(refresh, REFRESH_MS);
  document.body.dataset.ready = "1";
}

init().catch((err) => { $("health").textContent = String(err); $("health").className = "error"; });
