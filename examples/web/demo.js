// Demo for momloc-client.js: the room in perspective (plain canvas 2D, no library), one marker
// per person (a 1.7 m post with a head, coloured by id, faded by confidence), interpolated at the
// display's frame rate. `window.momlocDemo` exposes the state for tests and the console.
import { MomlocClient, defaultStreamUrl } from "./momloc-client.js";

const params = new URLSearchParams(location.search);
const token = params.get("token") ?? "";
const client = new MomlocClient({ url: params.get("stream") ?? defaultStreamUrl(), token });
const canvas = document.getElementById("scene");
const status = document.getElementById("status");
const ctx = canvas.getContext("2d");
const state = { client, floor: { xmin: 0, xmax: 10, ymin: 0, ymax: 10 }, markers: {}, draws: 0 };
window.momlocDemo = state;

async function loadFloor() {
  // the map extent the daemon uses (from its model); keep the default when it is not reachable
  const url = new URL("/v1/config", client.url.replace(/^ws/, "http"));
  if (token) url.searchParams.set("token", token);
  try {
    const response = await fetch(url);
    if (response.ok) {
      const config = await response.json();
      if (config.floor) state.floor = config.floor;
    }
  } catch (error) {
    console.warn("momloc demo: no /v1/config", error);
  }
}

// A pinhole camera above one corner of the floor looking at its centre; y is up, the floor is
// (x, 0, y) as in Unity / Three.js.
function makeCamera(width, height) {
  const f = state.floor;
  const cx = (f.xmin + f.xmax) / 2;
  const cz = (f.ymin + f.ymax) / 2;
  const size = Math.max(f.xmax - f.xmin, f.ymax - f.ymin);
  const eye = [cx - 0.2 * size, 0.9 * size, cz - 1.0 * size];
  const target = [cx, 0, cz];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => { const n = Math.hypot(...a); return [a[0] / n, a[1] / n, a[2] / n]; };
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const forward = norm(sub(target, eye));
  const right = norm(cross([0, 1, 0], forward));
  const up = cross(forward, right);
  const focal = (0.5 * height) / Math.tan((50 * Math.PI) / 360);
  return (x, h, y) => {
    const d = sub([x, h, y], eye);
    const z = dot(d, forward);
    if (z <= 0.01) return null;
    // screen x, y and pixels per metre at that depth (for sizes)
    return [width / 2 + (focal * dot(d, right)) / z, height / 2 - (focal * dot(d, up)) / z, focal / z];
  };
}

function colour(id, alpha) {
  return `hsla(${(id * 137.508) % 360}, 75%, 60%, ${alpha})`;
}

function draw() {
  const dpr = window.devicePixelRatio || 1;
  const width = canvas.clientWidth * dpr;
  const height = canvas.clientHeight * dpr;
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
  }
  ctx.fillStyle = "#111";
  ctx.fillRect(0, 0, width, height);
  const project = makeCamera(width, height);
  const f = state.floor;
  const line = (a, b) => {
    const p = project(...a);
    const q = project(...b);
    if (!p || !q) return;
    ctx.beginPath();
    ctx.moveTo(p[0], p[1]);
    ctx.lineTo(q[0], q[1]);
    ctx.stroke();
  };
  ctx.strokeStyle = "#333";
  ctx.lineWidth = dpr;
  for (let x = Math.ceil(f.xmin); x <= f.xmax; x++) line([x, 0, f.ymin], [x, 0, f.ymax]);
  for (let y = Math.ceil(f.ymin); y <= f.ymax; y++) line([f.xmin, 0, y], [f.xmax, 0, y]);

  const people = [...client.people().values()];
  const markers = {};
  const drawn = people
    .map((p) => ({ p, foot: project(p.x, 0, p.y), head: project(p.x, 1.7, p.y) }))
    .filter((m) => m.foot && m.head)
    .sort((a, b) => a.foot[2] - b.foot[2]); // far (fewer pixels per metre) first
  for (const { p, foot, head } of drawn) {
    const alpha = 0.25 + 0.75 * Math.max(0, Math.min(1, p.confidence));
    ctx.strokeStyle = colour(p.id, alpha);
    ctx.fillStyle = colour(p.id, alpha);
    ctx.lineWidth = Math.max(2, 0.08 * foot[2]);
    ctx.beginPath();
    ctx.moveTo(foot[0], foot[1]);
    ctx.lineTo(head[0], head[1]);
    ctx.stroke();
    ctx.beginPath();
    ctx.arc(head[0], head[1], Math.max(4, 0.15 * head[2]), 0, 2 * Math.PI);
    ctx.fill();
    ctx.fillStyle = "#eee";
    ctx.font = `${12 * dpr}px system-ui, sans-serif`;
    ctx.fillText(String(p.id), head[0] + 10 * dpr, head[1]);
    markers[p.id] = { x: p.x, y: p.y, sx: foot[0], sy: foot[1] };
  }
  state.markers = markers;
  state.draws += 1;
  status.textContent = client.tokenRejected
    ? "token rejected: open the page with ?token=…"
    : client.connected
      ? `connected · ${people.length} people · seq ${client.lastSnapshot?.seq ?? "-"}`
      : `reconnecting (attempt ${client.attempts})…`;
  status.className = client.connected ? "" : "bad";
  requestAnimationFrame(draw);
}

loadFloor().finally(() => {
  client.start();
  requestAnimationFrame(draw);
});
