// Live map: one WebSocket for positions, REST for config/health, previews.js for the cameras
// (snapshot.jpg, or boxes on an empty background under privacy: positions_only).
// window.momloc exposes the page state (people, seq, frames drawn) for tests and debugging.
"use strict";

const params = new URLSearchParams(location.search);
const token = params.get("token");
const TRAIL_S = 4.0;
const state = { people: {}, seq: 0, t: 0, draws: 0, connected: false, floor: null, fitted: null, moved: [],
  zones: [], occupancy: {}, toCanvas: null, privacy: null };
window.momloc = state;

function withToken(path) {
  if (!token) return path;
  return path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token);
}

const idColour = window.momlocPreviews.idColour; // the camera previews' colours

const trails = new Map(); // id -> [{t, x, y}]

function onSnapshot(snap) {
  state.seq = snap.seq;
  state.t = snap.t;
  const seen = {};
  for (const p of snap.people) {
    seen[p.id] = p;
    const trail = trails.get(p.id) || [];
    trail.push({ t: snap.t, x: p.x, y: p.y });
    while (trail.length && snap.t - trail[0].t > TRAIL_S) trail.shift();
    trails.set(p.id, trail);
  }
  for (const id of [...trails.keys()]) if (!(id in seen)) trails.delete(id);
  state.people = seen;
  document.getElementById("people-count").textContent = snap.people.length;
  document.getElementById("seq").textContent = snap.seq;
  renderList(snap.people);
}

function renderList(people) {
  const list = document.getElementById("people-list");
  list.replaceChildren(...people.map((p) => {
    const li = document.createElement("li");
    li.style.setProperty("--c", idColour(p.id));
    li.dataset.id = p.id; li.dataset.x = p.x; li.dataset.y = p.y;
    const speed = Math.hypot(p.vx, p.vy);
    li.textContent = `#${p.id}  x ${p.x.toFixed(2)}  y ${p.y.toFixed(2)} m  ${speed.toFixed(2)} m/s  cams [${p.cameras.join(",")}]`;
    return li;
  }));
}

function extent() {
  if (state.floor) return state.floor;
  // No configured floor: grow a box around everything seen so far.
  const f = state.fitted || { xmin: -1, xmax: 1, ymin: -1, ymax: 1 };
  for (const p of Object.values(state.people)) {
    f.xmin = Math.min(f.xmin, p.x - 1); f.xmax = Math.max(f.xmax, p.x + 1);
    f.ymin = Math.min(f.ymin, p.y - 1); f.ymax = Math.max(f.ymax, p.y + 1);
  }
  state.fitted = f;
  return f;
}

function draw() {
  const canvas = document.getElementById("map");
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, pad = 40;
  const f = extent();
  const scale = Math.min((W - 2 * pad) / (f.xmax - f.xmin), (H - 2 * pad) / (f.ymax - f.ymin));
  const ox = (W - scale * (f.xmax - f.xmin)) / 2, oy = (H - scale * (f.ymax - f.ymin)) / 2;
  const px = (x) => ox + (x - f.xmin) * scale;
  const py = (y) => H - oy - (y - f.ymin) * scale; // y up
  ctx.clearRect(0, 0, W, H);
  // floor and 1 m grid
  ctx.fillStyle = "#161b22";
  ctx.fillRect(px(f.xmin), py(f.ymax), scale * (f.xmax - f.xmin), scale * (f.ymax - f.ymin));
  ctx.strokeStyle = "#263040"; ctx.lineWidth = 1; ctx.fillStyle = "#6b7687"; ctx.font = "11px system-ui";
  for (let x = Math.ceil(f.xmin); x <= f.xmax; x++) {
    ctx.beginPath(); ctx.moveTo(px(x), py(f.ymin)); ctx.lineTo(px(x), py(f.ymax)); ctx.stroke();
    ctx.fillText(`${x}`, px(x) - 3, py(f.ymin) + 14);
  }
  for (let y = Math.ceil(f.ymin); y <= f.ymax; y++) {
    ctx.beginPath(); ctx.moveTo(px(f.xmin), py(y)); ctx.lineTo(px(f.xmax), py(y)); ctx.stroke();
    ctx.fillText(`${y}`, px(f.xmin) - 18, py(y) + 4);
  }
  ctx.strokeStyle = "#3b4657"; ctx.lineWidth = 2;
  ctx.strokeRect(px(f.xmin), py(f.ymax), scale * (f.xmax - f.xmin), scale * (f.ymax - f.ymin));
  state.toCanvas = (x, y) => [px(x), py(y)];
  drawZones(ctx, px, py);
  // people: trail, velocity arrow (1 s ahead), dot, id
  for (const p of Object.values(state.people)) {
    const trail = trails.get(p.id) || [];
    ctx.lineWidth = 3; ctx.lineCap = "round";
    for (let i = 1; i < trail.length; i++) {
      const a = (i / trail.length) * 0.8;
      ctx.strokeStyle = idColour(p.id, a);
      ctx.beginPath(); ctx.moveTo(px(trail[i - 1].x), py(trail[i - 1].y));
      ctx.lineTo(px(trail[i].x), py(trail[i].y)); ctx.stroke();
    }
    const x = px(p.x), y = py(p.y), tx = px(p.x + p.vx), ty = py(p.y + p.vy);
    if (Math.hypot(tx - x, ty - y) > 4) {
      const ang = Math.atan2(ty - y, tx - x);
      ctx.strokeStyle = idColour(p.id); ctx.fillStyle = idColour(p.id); ctx.lineWidth = 2;
      ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(tx, ty); ctx.stroke();
      ctx.beginPath(); ctx.moveTo(tx, ty);
      ctx.lineTo(tx - 9 * Math.cos(ang - 0.4), ty - 9 * Math.sin(ang - 0.4));
      ctx.lineTo(tx - 9 * Math.cos(ang + 0.4), ty - 9 * Math.sin(ang + 0.4));
      ctx.closePath(); ctx.fill();
    }
    ctx.globalAlpha = 0.35 + 0.65 * p.confidence;
    ctx.fillStyle = idColour(p.id);
    ctx.beginPath(); ctx.arc(x, y, 10, 0, 2 * Math.PI); ctx.fill();
    ctx.globalAlpha = 1;
    ctx.strokeStyle = "#0d1014"; ctx.lineWidth = 2; ctx.stroke();
    ctx.fillStyle = "#e7ecf2"; ctx.font = "bold 13px system-ui";
    ctx.fillText(`#${p.id}`, x + 13, y - 10);
  }
  state.draws++;
  requestAnimationFrame(draw);
}

// Zones (settings `zones`): outlined polygons, filled brighter while someone is inside.
function drawZones(ctx, px, py) {
  for (const z of state.zones) {
    const occ = state.occupancy[z.name];
    const busy = Boolean(occ && occ.count > 0);
    ctx.beginPath();
    z.polygon.forEach(([x, y], i) => (i ? ctx.lineTo(px(x), py(y)) : ctx.moveTo(px(x), py(y))));
    ctx.closePath();
    ctx.fillStyle = busy ? "rgba(240, 180, 60, 0.28)" : "rgba(88, 166, 255, 0.12)";
    ctx.fill();
    ctx.strokeStyle = busy ? "#f0b43c" : "#58a6ff"; ctx.lineWidth = 2; ctx.setLineDash([6, 4]);
    ctx.stroke(); ctx.setLineDash([]);
    const [lx, ly] = z.polygon.reduce(([a, b], [x, y]) => [Math.min(a, x), Math.max(b, y)], [Infinity, -Infinity]);
    ctx.fillStyle = busy ? "#f0b43c" : "#8ab8f0"; ctx.font = "bold 12px system-ui";
    ctx.fillText(`${z.name} · ${occ ? occ.count : 0}`, px(lx) + 6, py(ly) + 16);
  }
}

async function refreshZones() {
  if (!state.zones.length) return;
  try {
    const z = await getJSON("/v1/zones");
    state.occupancy = Object.fromEntries(z.zones.map((o) => [o.name, { count: o.count, ids: o.ids }]));
    document.getElementById("zones").replaceChildren(...z.zones.map((o) => {
      const li = document.createElement("li");
      li.dataset.zone = o.name; li.dataset.count = o.count;
      li.className = o.count > 0 ? "busy" : "";
      li.textContent = `${o.name}: ${o.count}` + (o.ids.length ? `  (#${o.ids.join(", #")})` : "");
      return li;
    }));
  } catch (e) { /* offline: keep the last state */ }
}

function setLink(ok, text) {
  state.connected = ok;
  const el = document.getElementById("link");
  el.textContent = text; el.className = "pill " + (ok ? "ok" : "bad");
}

let backoff = 500;
function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(withToken(`${scheme}://${location.host}/v1/stream`));
  ws.onopen = () => { backoff = 500; setLink(true, "live"); };
  ws.onmessage = (ev) => onSnapshot(JSON.parse(ev.data));
  ws.onclose = (ev) => {
    setLink(false, ev.code === 4401 ? "token rejected" : "reconnecting…");
    if (ev.code !== 4401) setTimeout(connect, backoff);
    backoff = Math.min(backoff * 2, 5000);
  };
}

async function getJSON(path) {
  const r = await fetch(withToken(path));
  if (!r.ok) throw new Error(`${path}: ${r.status}`);
  return r.json();
}

function row(label, value, good) {
  const tr = document.createElement("tr");
  const a = document.createElement("td"); a.textContent = label;
  const b = document.createElement("td"); b.textContent = value;
  if (good !== undefined) b.className = good ? "good" : "warn";
  tr.append(a, b);
  return tr;
}

async function refreshHealth() {
  try {
    const h = await getJSON("/v1/health");
    const p = h.pipeline;
    document.getElementById("pipeline-fps").textContent = p.fps.toFixed(1);
    document.getElementById("latency").textContent = p.latency_ms.p95 == null ? "–" : p.latency_ms.p95.toFixed(0);
    const rows = [row("status", h.status, h.status === "ok"),
      row("model", h.model.loaded ? (h.model.compatible ? "loaded" : h.model.problem) : (h.model.message || "not loaded"), h.model.loaded && h.model.compatible),
      ...(h.model.verification ? [row("checked", h.model.verification.text, true)] : []),
      row("pipeline", `${p.fps.toFixed(1)} fps, p50 ${p.latency_ms.p50 ?? "–"} ms`, p.running && !p.error),
      row("dropped frames", String(p.frames_dropped)), row("clients", String(h.clients)),
      row("privacy", h.privacy === "positions_only" ? "positions only: no camera images" : h.privacy)];
    for (const c of h.cameras) {
      const moved = Boolean(c.alignment && c.alignment.moved);
      rows.push(row(`cam ${c.index} ${c.name}`, (c.connected ? `${(c.fps ?? 0).toFixed(1)} fps, age ${((c.last_frame_age ?? 0) * 1000).toFixed(0)} ms` : (c.error || "disconnected")) + (moved ? " · MOVED" : ""), c.connected && !moved));
    }
    const learning = h.learning || {};
    if (learning.enabled) rows.push(row("learned from", `${learning.self_labels.toLocaleString("en-US")} positions`, true));
    for (const r of learning.repairs || []) rows.push(row(`repair cam ${r.camera}`, r.message, r.state === "repaired"));
    if (p.error) rows.push(row("error", p.error, false));
    document.querySelector("#health tbody").replaceChildren(...rows);
    showMoved(h.cameras);
    document.getElementById("setup-banner").hidden = !h.setup_mode;
  } catch (e) { /* server restarting: the WebSocket pill already says so */ }
}

// Camera-moved alert: a banner naming each moved camera and what to do; its preview is outlined.
function showMoved(cameras) {
  const moved = cameras.filter((c) => c.alignment && c.alignment.moved);
  state.moved = moved.map((c) => c.index);
  const banner = document.getElementById("moved-banner");
  banner.hidden = moved.length === 0;
  banner.replaceChildren(...moved.map((c) => {
    const line = document.createElement("p");
    const title = document.createElement("b");
    title.textContent = `Camera ${c.index} (${c.name}) has moved. `;
    // health says "camera k (name) was moved: why; what to do": the title already names it
    const msg = c.alignment.message || "re-collect the floor marks (momloc collect, or the /setup page) and retrain (momloc train)";
    const detail = msg.includes(": ") ? msg.slice(msg.indexOf(": ") + 2) : msg;
    line.append(title, detail.charAt(0).toUpperCase() + detail.slice(1) + ".");
    if (c.repair) line.append(` ${c.repair.charAt(0).toUpperCase() + c.repair.slice(1)}.`); // self-healing
    return line;
  }));
  for (const fig of document.querySelectorAll("#cameras figure")) {
    const hit = state.moved.includes(Number(fig.dataset.k));
    fig.classList.toggle("moved", hit);
    const cap = fig.querySelector("figcaption");
    cap.textContent = cap.dataset.label + (hit ? " · MOVED" : "");
  }
}

const refreshPreviews = () => window.momlocPreviews.refresh("#cameras .preview", withToken);

async function init() {
  document.getElementById("setup-link").href = withToken("/setup");
  try {
    const cfg = await getJSON("/v1/config");
    state.floor = cfg.floor;
    state.zones = cfg.zones || [];
    state.privacy = cfg.privacy;
    document.getElementById("privacy").hidden = cfg.privacy !== "positions_only";
    document.getElementById("zones-panel").hidden = state.zones.length === 0;
    document.getElementById("cameras").replaceChildren(...cfg.cameras.map((c) => {
      const fig = document.createElement("figure"); fig.dataset.k = c.index;
      const preview = window.momlocPreviews.create(c.index, c.name, cfg.privacy);
      const cap = document.createElement("figcaption"); cap.dataset.label = `camera ${c.index} · ${c.name}`;
      cap.textContent = cap.dataset.label;
      fig.append(preview, cap);
      return fig;
    }));
  } catch (e) { setLink(false, "unauthorized or offline"); }
  connect();
  refreshHealth(); setInterval(refreshHealth, 1000);
  refreshZones(); setInterval(refreshZones, 500);
  refreshPreviews(); setInterval(refreshPreviews, 400);
  requestAnimationFrame(draw);
}

init();
