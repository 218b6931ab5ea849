// Guided collection page: starts a collection on the daemon and follows its progress.
"use strict";
const params = new URLSearchParams(location.search);
const token = params.get("token");
const headers = { "Content-Type": "application/json" };
if (token) headers.Authorization = "Bearer " + token;
const $ = (id) => document.getElementById(id);
let modelDir = null;
if (token) $("map-link").href = "/?token=" + encodeURIComponent(token);

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

$("start").addEventListener("click", async () => {
  $("error").textContent = "";
  try {
    const body = { seconds: parseFloat($("seconds").value), walk: $("walk").checked, out: $("out").value.trim() };
    if (document.querySelector("input[name=mode]:checked").value === "grid") {
      body.grid = $("grid").value.trim();
      body.room = $("room").value.trim();
    } else {
      body.marks = parseMarks($("marks").value);
    }
    render(await call("POST", "/v1/setup/start", body));
  } catch (err) {
    $("error").textContent = err.message;
  }
});
$("stop").addEventListener("click", async () => render(await call("POST", "/v1/setup/stop", {})));
$("reload").addEventListener("click", async () => {
  try {
    const info = await call("POST", "/v1/model/reload", { model_dir: modelDir });
    $("reload-result").textContent = `loaded ${info.path}`;
  } catch (err) {
    $("reload-result").textContent = err.message;
  }
});

function chip(k, n) {
  const [cls, text] = n === 0 ? ["none", "not seen"] : n === 1 ? ["seen", "seen"] : ["many", `${n} people!`];
  return `<span class="chip ${cls}">camera ${k}: ${text}</span>`;
}

function render(s) {
  const running = s.state === "running";
  $("state").textContent = s.state;
  $("state").className = "pill " + (running ? "ok" : "bad");
  $("start").disabled = running;
  $("stop").disabled = !running;
  if (s.instruction) $("instruction").textContent = s.instruction;
  $("countdown").textContent = running && (s.kind === "countdown" || s.kind === "move") ? Math.ceil(s.remaining_s) : "";
  $("step-progress").value = s.fraction || 0;
  $("step-count").textContent = s.steps ? `step ${(s.step_index || 0) + 1} of ${s.steps}` : "";
  $("camera-chips").innerHTML = (s.cameras_seeing || []).map((n, k) => chip(k, n)).join("");
  const resumed = (s.skipped_marks || []).length ? ` · already recorded: ${s.skipped_marks.join(", ")}` : "";
  const again = (s.incomplete_marks || []).length ? ` · interrupted before, recording again: ${s.incomplete_marks.join(", ")}` : "";
  $("rows").textContent = s.new_rows !== undefined ? `${s.new_rows} frames kept` + (s.existing_rows ? ` (+${s.existing_rows} from before)` : "") + resumed + again : "";
  if (s.error) $("error").textContent = s.error;
  const finished = s.state === "done" || s.state === "stopped";
  $("next").hidden = !finished;
  if (finished && s.out) $("train-cmd").textContent = `momloc train ${s.out} --out ${s.model_dir}`;
  modelDir = s.model_dir || modelDir;
}

async function poll() {
  try {
    render(await call("GET", "/v1/setup/status"));
  } catch (err) {
    $("error").textContent = err.message;
  }
  setTimeout(poll, 250);
}
poll();
