// Camera previews shared by the live map and the set-up page. Normally an <img> of
// /v1/cameras/k/snapshot.jpg (the daemon draws the boxes on the frame). Under
// privacy: positions_only no image leaves the daemon, so the preview is a <canvas> with the same
// boxes and track ids from /v1/cameras/k/boxes drawn on an empty background.
// window.momlocPreviews.drawn counts the canvas redraws (for tests).
"use strict";
window.momlocPreviews = (() => {
  const PRIVATE = "positions_only";
  const WIDTH = 320;
  const api = { drawn: 0 };

  // Same colour per id as the daemon's JPEG boxes (OpenCV hue = id * 47 mod 180, in degrees x2).
  api.idColour = (id, alpha = 1) => `hsla(${((id * 47) % 180) * 2}, 85%, 60%, ${alpha})`;

  // The preview element of camera `k`: an <img>, or a <canvas> under privacy: positions_only.
  api.create = (k, name, privacy) => {
    const el = document.createElement(privacy === PRIVATE ? "canvas" : "img");
    el.dataset.k = k;
    el.className = "preview";
    if (el.tagName === "IMG") el.alt = name;
    else { el.width = WIDTH; el.height = WIDTH * 3 / 4; el.setAttribute("aria-label", `boxes seen by ${name}`); }
    return el;
  };

  function drawBoxes(canvas, view) {
    const w = view.width || 640, h = view.height || 480;
    canvas.height = Math.round(WIDTH * h / w);
    const s = WIDTH / w, ctx = canvas.getContext("2d");
    ctx.fillStyle = "#0d1014"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.fillStyle = "#59616e"; ctx.font = "11px system-ui";
    ctx.fillText("positions only: no camera image", 6, canvas.height - 6);
    ctx.lineWidth = 2; ctx.font = "bold 12px system-ui";
    for (const { box: [x0, y0, x1, y1], id } of view.boxes) {
      ctx.strokeStyle = id == null ? "#a0a0a0" : api.idColour(id);
      ctx.strokeRect(x0 * s, y0 * s, (x1 - x0) * s, (y1 - y0) * s);
      if (id != null) { ctx.fillStyle = ctx.strokeStyle; ctx.fillText(`#${id}`, x0 * s + 3, Math.max(y0 * s - 4, 12)); }
    }
    canvas.dataset.boxes = view.boxes.length;
    api.drawn++;
  }

  // Refresh every preview under `selector`; `withToken(path)` adds the page's token.
  api.refresh = (selector, withToken) => {
    for (const el of document.querySelectorAll(selector)) {
      if (el.dataset.loading === "1") continue; // skip a tick rather than queue requests
      el.dataset.loading = "1";
      const done = () => { el.dataset.loading = "0"; };
      if (el.tagName === "CANVAS") {
        fetch(withToken(`/v1/cameras/${el.dataset.k}/boxes`))
          .then((r) => (r.ok ? r.json() : Promise.reject(new Error(r.status))))
          .then((view) => drawBoxes(el, view)).catch(() => {}).finally(done);
        continue;
      }
      const next = new Image();
      next.onload = () => { el.src = next.src; done(); };
      next.onerror = done;
      next.src = withToken(`/v1/cameras/${el.dataset.k}/snapshot.jpg?width=${WIDTH}&quality=70&n=${Date.now()}`);
    }
  };
  return api;
})();
