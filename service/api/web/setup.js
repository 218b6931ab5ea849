// Set-up page: see (previews with boxes, previews.js; who each camera sees, floor plan), record (per-mark
// quality, record again), train (background process, live epochs), check (error per mark).
// window.momlocSetup exposes the last status for tests and debugging.
"use strict";
const params = new URLSearchParams(location.search);
const token = params.get("token");
const headers = { "Content-Type": "application/json" };
if (token) headers.Authorization = "Bearer " + token;
const $ = (id) => document.getElementById(id);
const view = { status: null, floor: null, cameras: [], people: [], setupMode: true, privacy: null };
window.momlocSetup = view;
const withToken = (path) => (token ? path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token) : path);
$("map-link").href = withToken("/");
$("to-map").href = withToken("/");

document.querySelectorAll("input[name=mode]").forEach((radio) =>
  radio.addEventListener("change", () => {
    const grid = document.querySelector("input[name=mode]:checked").value === "grid";
    $("grid-fields").hidden = !grid;
    $("list-fields").hidden = grid;
  }));

function parseMarks(text) {
  return text.split("\n").map((l) => l.trim()).filter(Boolean).map((line, i) => {
    const [name, x, y] = line.split(/[\s,;]+/);
    if (Number.isNaN(parseFloat(x)) || Number.isNaN(parseFloat(y))) throw new Error(`line ${i + 1}: expected "name x y"`);
    return { name, x: parseFloat(x), y: parseFloat(y) };
  });
}

async function call(method, path, body) {
  const response = await fetch(path, { method, headers, body: body ? JSON.stringify(body) : undefined });
  const data = await response.json().catch(() => ({}));
  if (!response.ok) {
    const detail = Array.isArray(data.detail) ? data.detail.map((d) => `${d.loc.slice(-1)}: ${d.msg}`).join("; ") : data.detail;
    throw new Error(detail || response.statusText);
  }
  return data;
}

async function act(fn) {
  $("error").textContent = "";
  try { await fn(); } catch (err) { $("error").textContent = err.message; }
}

const number = (id) => parseFloat($(id).value);
$("start").addEventListener("click", () => act(async () => {
  const body = { seconds: number("seconds"), move_seconds: number("move-seconds"), countdown: number("countdown-seconds"),
    walk: $("walk").checked, out: $("out").value.trim() };
  if (document.querySelector("input[name=mode]:checked").value === "grid") {
    body.grid = $("grid").value.trim();
    body.room = $("room").value.trim();
  } else {
    body.marks = parseMarks($("marks").value);
  }
  await call("POST", "/v1/setup/start", body);
}));
$("stop").addEventListener("click", () => act(() => call("POST", "/v1/setup/stop", {})));
$("train").addEventListener("click", () => act(() => {
  const epochs = parseInt($("epochs").value, 10);
  const recording = view.status && view.status.out ? view.status.out.split("/").pop() : undefined;
  return call("POST", "/v1/setup/train", { recording, epochs: Number.isNaN(epochs) ? undefined : epochs });
}));
$("train-cancel").addEventListener("click", () => act(() => call("POST", "/v1/setup/train/cancel", {})));
$("verify").addEventListener("click", () => act(() => {
  const text = $("verify-marks").value.trim();
  const body = { seconds: number("verify-seconds"), move_seconds: number("move-seconds"), countdown: number("countdown-seconds") };
  if (text) body.marks = parseMarks(text);
  return call("POST", "/v1/setup/verify", body);
}));
$("verify-stop").addEventListener("click", () => act(() => call("POST", "/v1/setup/verify/stop", {})));
$("quality").addEventListener("click", (event) => {
  const mark = event.target.dataset && event.target.dataset.again;
  if (mark) act(() => call("POST", "/v1/setup/record-again", { mark }));
});

// -- see: previews with the detector's boxes, and whether each camera sees exactly one person --
function buildPreviews(cameras) {
  $("previews").replaceChildren(...cameras.map((c) => {
    const fig = document.createElement("figure"); fig.dataset.k = c.index;
    const preview = window.momlocPreviews.create(c.index, `camera ${c.index} (${c.name})`, view.privacy);
    const cap = document.createElement("figcaption"); cap.textContent = `camera ${c.index} · ${c.name}`;
    fig.append(preview, cap);
    return fig;
  }));
}

function seeing(counts) {
  for (const fig of document.querySelectorAll("#previews figure")) {
    const k = Number(fig.dataset.k), n = counts[k] ?? 0;
    const name = view.cameras[k] ? view.cameras[k].name : "";
    const text = n === 1 ? "sees 1 person ✓" : n === 0 ? "sees nobody" : `sees ${n} people: one at a time!`;
    fig.className = n === 1 ? "one" : n > 1 ? "many" : "none";
    fig.querySelector("figcaption").textContent = `camera ${k} · ${name} · ${text}`;
  }
}

const refreshPreviews = () => window.momlocPreviews.refresh("#previews .preview", withToken);

// -- the floor plan, to scale: the room (settings, synthetic scene or grid), else the marks --
function planExtent(marks) {
  if (view.floor) return view.floor;
  const room = ($("room").value || "").split(/[x×X]/).map(parseFloat);
  if (document.querySelector("input[name=mode]:checked").value === "grid" && room.length === 2 && room.every((v) => v > 0)) {
    return { xmin: 0, xmax: room[0], ymin: 0, ymax: room[1] };
  }
  if (!marks.length) return { xmin: 0, xmax: 4, ymin: 0, ymax: 4 };
  const xs = marks.map((m) => m.x), ys = marks.map((m) => m.y);
  return { xmin: Math.min(...xs) - 0.5, xmax: Math.max(...xs) + 0.5, ymin: Math.min(...ys) - 0.5, ymax: Math.max(...ys) + 0.5 };
}

const COLOURS = { done: "#3ecf8e", current: "#f5c542", todo: "#59616e" };
function drawPlan() {
  const canvas = $("floor-plan"), ctx = canvas.getContext("2d");
  const s = view.status || {};
  const marks = s.marks || [];
  const checks = (s.verify && s.verify.marks) || [];
  const e = planExtent(marks);
  const pad = 24, w = canvas.width - 2 * pad, h = canvas.height - 2 * pad;
  const scale = Math.min(w / (e.xmax - e.xmin), h / (e.ymax - e.ymin)); // same scale on both axes
  const px = (x) => pad + (x - e.xmin) * scale, py = (y) => canvas.height - pad - (y - e.ymin) * scale;
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.strokeStyle = "#222a35"; ctx.lineWidth = 1;
  for (let x = Math.ceil(e.xmin); x <= e.xmax; x++) { ctx.beginPath(); ctx.moveTo(px(x), py(e.ymin)); ctx.lineTo(px(x), py(e.ymax)); ctx.stroke(); }
  for (let y = Math.ceil(e.ymin); y <= e.ymax; y++) { ctx.beginPath(); ctx.moveTo(px(e.xmin), py(y)); ctx.lineTo(px(e.xmax), py(y)); ctx.stroke(); }
  ctx.strokeStyle = "#5b6574"; ctx.strokeRect(px(e.xmin), py(e.ymax), (e.xmax - e.xmin) * scale, (e.ymax - e.ymin) * scale);
  ctx.font = "12px system-ui"; ctx.textBaseline = "middle";
  for (const m of marks) {
    ctx.fillStyle = COLOURS[m.state] || COLOURS.todo;
    ctx.beginPath(); ctx.arc(px(m.x), py(m.y), m.state === "current" ? 9 : 6, 0, 2 * Math.PI); ctx.fill();
    ctx.fillStyle = "#e7ecf2"; ctx.fillText(m.name, px(m.x) + 11, py(m.y));
  }
  for (const m of checks) {
    ctx.strokeStyle = s.verify.mark === m.name ? COLOURS.current : "#a0a8b4"; ctx.lineWidth = 2;
    ctx.strokeRect(px(m.x) - 7, py(m.y) - 7, 14, 14);
    ctx.fillStyle = "#e7ecf2"; ctx.fillText(m.name + (m.error_m != null ? ` ${m.error_m.toFixed(2)} m` : ""), px(m.x) + 11, py(m.y) + 14);
  }
  for (const p of view.people) {
    ctx.fillStyle = "#5b8def"; ctx.beginPath(); ctx.arc(px(p.x), py(p.y), 7, 0, 2 * Math.PI); ctx.fill();
  }
}

// -- record: per-mark quality, with "record again" --
function renderQuality(quality, running) {
  $("quality-panel").hidden = !quality.length;
  $("quality").querySelector("tbody").replaceChildren(...quality.map((q) => {
    const tr = document.createElement("tr");
    const low = q.per_camera.map((n) => n < 0.3 * q.frames);
    tr.innerHTML = `<td>${q.mark}</td><td>${q.frames}</td><td>${q.per_camera.map((n, k) => `<span class="${low[k] ? "low" : ""}">cam ${k}: ${n}</span>`).join(" · ")}</td>`;
    const td = document.createElement("td");
    const again = document.createElement("button");
    again.textContent = "record this mark again"; again.dataset.again = q.mark; again.disabled = running;
    td.append(again); tr.append(td);
    return tr;
  }));
  $("quality-warnings").replaceChildren(...quality.flatMap((q) => q.warnings).map((w) => {
    const li = document.createElement("li"); li.textContent = w; return li;
  }));
}

// -- train and check --
function renderTraining(t, recorded) {
  $("train-panel").hidden = !recorded && t.state === "idle";
  const running = t.state === "running";
  $("train").disabled = running;
  $("train-cancel").disabled = !running;
  $("train-progress").value = t.epoch && t.max_epochs ? t.epoch / t.max_epochs : t.state === "done" ? 1 : 0;
  const progress = t.epoch ? `epoch ${t.epoch}${t.max_epochs ? " of " + t.max_epochs : ""}, median validation error ${t.val_median_m.toFixed(3)} m` : "";
  const first = t.first_model ? `first model loaded (${t.first_model.epochs} epochs in ${t.first_model.seconds} s, median validation error ${t.first_model.val_median_m.toFixed(3)} m): positions are on the live map; ` : "";
  const stage = t.stage === "first" && (t.stages || []).length > 1 ? "training a quick first model…" : first ? "final model training…" : "training…";
  $("train-state").textContent = running ? `${first}${stage} ${progress}`
    : t.state === "done" ? `trained (${progress}); model loaded from ${t.model_dir}: positions are on the live map`
    : t.state === "failed" ? `training failed: ${t.error}` : "";
  $("train-state").className = t.state === "failed" ? "warn" : "hint";
}

function renderVerify(v, modelLoaded) {
  $("verify-panel").hidden = !modelLoaded && v.state === "idle";
  const running = v.state === "running";
  $("verify").disabled = running || !modelLoaded;
  $("verify-stop").disabled = !running;
  $("verify-table").querySelector("tbody").replaceChildren(...(v.marks || []).map((m) => {
    const tr = document.createElement("tr");
    const live = running && v.mark === m.name && v.live_error_m != null ? ` (now ${v.live_error_m.toFixed(2)} m)` : "";
    tr.innerHTML = `<td>${m.name}</td><td>${m.error_m != null ? m.error_m.toFixed(2) + " m" : running ? "…" : "not seen"}${live}</td>`;
    return tr;
  }));
  $("verify-summary").textContent = v.summary ? v.summary.text : "";
  $("done-link").hidden = !v.summary;
}

function render(s) {
  view.status = s;
  const t = s.training || { state: "idle" }, v = s.verify || { state: "idle" };
  const running = s.state === "running";
  const busy = running ? s.state : t.state === "running" ? "training" : v.state === "running" ? "checking" : s.state;
  $("state").textContent = busy;
  $("state").className = "pill " + (running || t.state === "running" || v.state === "running" ? "ok" : "bad");
  $("start").disabled = running || t.state === "running";
  $("stop").disabled = !running;
  const instruction = v.state === "running" ? v.instruction : s.instruction;
  if (instruction) $("instruction").textContent = instruction;
  const kind = v.state === "running" ? v.kind : s.kind;
  const remaining = v.state === "running" ? v.remaining_s : s.remaining_s;
  $("countdown").textContent = (running || v.state === "running") && (kind === "countdown" || kind === "move") ? Math.ceil(remaining) : "";
  $("step-progress").value = running ? s.fraction || 0 : 0;
  $("step-count").textContent = running && s.steps ? `step ${(s.step_index || 0) + 1} of ${s.steps}` : "";
  seeing(running && s.cameras_seeing ? s.cameras_seeing : s.cameras_now || []);
  const resumed = (s.skipped_marks || []).length ? ` · already recorded: ${s.skipped_marks.join(", ")}` : "";
  const again = (s.incomplete_marks || []).length ? ` · interrupted before, recording again: ${s.incomplete_marks.join(", ")}` : "";
  $("rows").textContent = s.new_rows !== undefined ? `${s.new_rows} frames kept` + (s.existing_rows ? ` (+${s.existing_rows} from before)` : "") + resumed + again : "";
  if (s.error) $("error").textContent = s.error;
  renderQuality(s.quality || [], running);
  const recorded = s.state === "done" || s.state === "stopped";
  renderTraining(t, recorded);
  renderVerify(v, !view.setupMode);
  drawPlan();
}

async function refreshHealth() {
  try {
    const h = await call("GET", "/v1/health");
    view.setupMode = h.setup_mode;
    $("intro").textContent = h.setup_mode
      ? "No model yet: tape a few marks on the floor, record them here, train, check; then positions appear on the live map."
      : `Model loaded from ${h.model.path}${h.model.verification ? " · checked: " + h.model.verification.text : ""}. Record and train again to replace it.`;
    renderLearning(h.learning);
    if (!h.setup_mode) view.people = (await call("GET", "/v1/positions")).people;
  } catch (err) { /* restarting: the status poll shows errors */ }
}

// The room that learns (/v1/health learning): positions learned from, the last improvement.
function renderLearning(l) {
  const line = $("learning");
  line.hidden = !l || !l.enabled;
  if (line.hidden) return;
  const parts = [`Learned from ${l.self_labels.toLocaleString("en-US")} positions of people walking`];
  const last = l.improvement && l.improvement.last;
  if (last) parts.push(last.reason);
  for (const r of l.repairs || []) parts.push(r.message);
  line.textContent = parts.join(" · ") + ".";
}

async function poll() {
  try {
    render(await call("GET", "/v1/setup/status"));
  } catch (err) {
    $("error").textContent = err.message;
  }
  setTimeout(poll, 250);
}

async function init() {
  try {
    const cfg = await call("GET", "/v1/config");
    view.floor = cfg.floor;
    view.cameras = cfg.cameras;
    view.setupMode = cfg.setup_mode;
    view.privacy = cfg.privacy;
    buildPreviews(cfg.cameras);
  } catch (err) { $("error").textContent = err.message; }
  poll();
  refreshHealth(); setInterval(refreshHealth, 500);
  refreshPreviews(); setInterval(refreshPreviews, 300);
}
init();
