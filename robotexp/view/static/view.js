// robotexp live view: draws the frames the server sends on /ws (see robotexp/view/feed.py).
"use strict";
(() => {
  const $ = (id) => document.getElementById(id);
  const canvas = $("map"), ctx = canvas.getContext("2d");
  const curveCanvas = $("curve"), cctx = curveCanvas.getContext("2d");
  const S = { meta: null, pose: null, laser: [], path: [], curve: [], overlays: {}, status: {},
              mapCanvas: null, potCanvas: null, mapVersion: 0, t: 0, controls: [] };
  const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];

  function viridis(v) {
    const x = Math.min(Math.max(v, 0), 1) * 4, i = Math.min(Math.floor(x), 3), f = x - i;
    return VIRIDIS[i].map((c, k) => Math.round(c + f * (VIRIDIS[i + 1][k] - c)));
  }

  async function inflate(b64) {
    const bin = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
    const stream = new Blob([bin]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Uint8Array(await new Response(stream).arrayBuffer());
  }

  // a layer of rows x cols cells (row 0 = south) drawn north-up into an offscreen canvas
  function layerCanvas(bytes, rows, cols, colour) {
    const off = document.createElement("canvas");
    off.width = cols; off.height = rows;
    const img = off.getContext("2d").createImageData(cols, rows);
    for (let r = 0; r < rows; r++) {
      const dst = (rows - 1 - r) * cols;
      for (let c = 0; c < cols; c++) {
        const rgba = colour(bytes[r * cols + c]), o = (dst + c) * 4;
        img.data[o] = rgba[0]; img.data[o + 1] = rgba[1]; img.data[o + 2] = rgba[2]; img.data[o + 3] = rgba[3];
      }
    }
    off.getContext("2d").putImageData(img, 0, 0);
    return off;
  }
  const CLASS_RGBA = [[205, 205, 205, 255], [255, 255, 255, 255], [0, 0, 0, 255]];

  // world [m] -> canvas [px]
  function transform() {
    const g = S.meta.geo, w = g.cols * g.cell, h = g.rows * g.cell;
    const k = Math.min(canvas.width / w, canvas.height / h);
    const ox = (canvas.width - w * k) / 2, oy = (canvas.height - h * k) / 2;
    return { k, px: (x) => ox + (x - g.origin_x) * k, py: (y) => oy + h * k - (y - g.origin_y) * k, ox, oy, w, h };
  }

  function fitCanvas() {
    if (!S.meta) return;
    const g = S.meta.geo, box = $("mapbox").clientWidth - 16;
    const aspect = g.rows / g.cols, width = Math.max(300, Math.min(box, 1600));
    const height = Math.round(Math.min(width * aspect, window.innerHeight * 0.82));
    const dpr = window.devicePixelRatio || 1;
    canvas.width = Math.round(width * dpr); canvas.height = Math.round(height * dpr);
    canvas.style.height = height + "px";
  }

  // the background (map, overlays, path) is drawn into its own canvas when it changes, new path
  // segments are added to it as they come; each frame copies it and draws the laser and the robot
  const bg = document.createElement("canvas"), bgx = bg.getContext("2d");
  let bgDirty = true, bgPath = 0;

  function drawBackground() {
    if (bg.width !== canvas.width || bg.height !== canvas.height) { bg.width = canvas.width; bg.height = canvas.height; }
    const ctx = bgx;
    ctx.fillStyle = "#cdcdcd"; ctx.fillRect(0, 0, bg.width, bg.height);
    bgDirty = false; bgPath = 0;
    if (!S.meta) return;
    const T = transform();
    ctx.imageSmoothingEnabled = false;
    if (S.mapCanvas) ctx.drawImage(S.mapCanvas, T.ox, T.oy, T.w * T.k, T.h * T.k);
    if (S.potCanvas) { ctx.globalAlpha = 0.7; ctx.drawImage(S.potCanvas, T.ox, T.oy, T.w * T.k, T.h * T.k);
                       ctx.globalAlpha = 1; }
    const lw = Math.max(1, canvas.width / 700);
    const ov = S.overlays || {};
    if (ov.vectors) {
      const a = ov.vectors.arrows, half = 0.4 * ov.vectors.spacing * T.k;
      ctx.strokeStyle = "rgba(25,25,25,0.75)"; ctx.lineWidth = lw * 0.8; ctx.beginPath();
      for (let i = 0; i < a.length; i += 4) {
        const x = T.px(a[i]), y = T.py(a[i + 1]), dx = a[i + 2] * half, dy = -a[i + 3] * half;
        ctx.moveTo(x - dx, y - dy); ctx.lineTo(x + dx, y + dy);
        ctx.moveTo(x + dx, y + dy); ctx.lineTo(x + dx * 0.4 - dy * 0.35, y + dy * 0.4 + dx * 0.35);
        ctx.moveTo(x + dx, y + dy); ctx.lineTo(x + dx * 0.4 + dy * 0.35, y + dy * 0.4 - dx * 0.35);
      }
      ctx.stroke();
    }
    if (ov.polygons) for (const polys of Object.values(ov.polygons)) {
      ctx.strokeStyle = "rgba(10,138,90,0.6)"; ctx.fillStyle = "rgba(10,138,90,0.10)"; ctx.lineWidth = lw;
      for (const p of polys) {
        if (p.length < 6) continue;
        ctx.beginPath(); ctx.moveTo(T.px(p[0]), T.py(p[1]));
        for (let i = 2; i < p.length; i += 2) ctx.lineTo(T.px(p[i]), T.py(p[i + 1]));
        ctx.closePath(); ctx.fill(); ctx.stroke();
      }
    }
    if (ov.circles) for (const [name, c] of Object.entries(ov.circles)) {
      ctx.strokeStyle = name.includes("region") ? "rgba(10,138,90,0.55)" : "#0a8a5a";
      ctx.fillStyle = "rgba(10,138,90,0.08)"; ctx.lineWidth = lw;
      for (let i = 0; i < c.length; i += 3) {
        ctx.beginPath(); ctx.arc(T.px(c[i]), T.py(c[i + 1]), c[i + 2] * T.k, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
      }
    }
    if (ov.lines) for (const l of Object.values(ov.lines)) {
      ctx.strokeStyle = "#0a8a5a"; ctx.lineWidth = lw * 1.5; ctx.beginPath();
      for (let i = 0; i < l.length; i += 4) { ctx.moveTo(T.px(l[i]), T.py(l[i + 1])); ctx.lineTo(T.px(l[i + 2]), T.py(l[i + 3])); }
      ctx.stroke();
    }
    if (ov.points) for (const [name, p] of Object.entries(ov.points)) {
      ctx.fillStyle = name.includes("node") ? "#0a8a5a" : "#b000b0";
      ctx.strokeStyle = "#fff"; ctx.lineWidth = lw;
      const r = Math.max(3, 0.12 * T.k);
      for (let i = 0; i < p.length; i += 2) {
        ctx.beginPath(); ctx.arc(T.px(p[i]), T.py(p[i + 1]), r, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
      }
    }
    drawPath(T);
  }

  function drawPath(T) {
    const ctx = bgx, lw = Math.max(1, canvas.width / 700);
    if (S.path.length < 4 || bgPath >= S.path.length - 2) return;
    const from = Math.max(bgPath - 2, 0);
    ctx.strokeStyle = "#1e5adc"; ctx.lineWidth = lw * 1.6; ctx.lineJoin = "round"; ctx.lineCap = "round"; ctx.beginPath();
    ctx.moveTo(T.px(S.path[from]), T.py(S.path[from + 1]));
    for (let i = from + 2; i < S.path.length; i += 2) ctx.lineTo(T.px(S.path[i]), T.py(S.path[i + 1]));
    ctx.stroke();
    bgPath = S.path.length;
  }

  function draw() {
    if (!S.meta) { ctx.fillStyle = "#cdcdcd"; ctx.fillRect(0, 0, canvas.width, canvas.height); return; }
    const T = transform(), lw = Math.max(1, canvas.width / 700);
    if (bgDirty || bg.width !== canvas.width || bg.height !== canvas.height) drawBackground(); else drawPath(T);
    ctx.drawImage(bg, 0, 0);
    // laser
    if (S.pose && S.laser.length) {
      ctx.fillStyle = "#ff8c00"; const d = Math.max(2, lw * 2.2);
      for (let i = 0; i < S.laser.length; i += 2) ctx.fillRect(T.px(S.laser[i]) - d / 2, T.py(S.laser[i + 1]) - d / 2, d, d);
    }
    if (S.meta.start) drawRobot(T, S.meta.start, "rgba(40,170,60,0.8)", lw, false);
    if (S.pose) drawRobot(T, S.pose, "#dc2828", lw, true);
  }

  function drawRobot(T, pose, colour, lw, filled) {
    const [x, y, th] = pose, r = Math.max(S.meta.radius * T.k, 4);
    const cx = T.px(x), cy = T.py(y);
    ctx.beginPath(); ctx.arc(cx, cy, r, 0, 2 * Math.PI);
    if (filled) { ctx.fillStyle = "rgba(220,40,40,0.25)"; ctx.fill(); }
    ctx.strokeStyle = colour; ctx.lineWidth = lw * 1.8; ctx.stroke();
    ctx.beginPath(); ctx.moveTo(cx, cy); ctx.lineTo(cx + Math.cos(th) * r * 1.6, cy - Math.sin(th) * r * 1.6); ctx.stroke();
  }

  function scaleText(g) {
    return `cell ${Math.round(g.cell * 1000)} mm · map ${(g.cols * g.cell).toFixed(1)} × ${(g.rows * g.cell).toFixed(1)} m`;
  }

  function drawCurve() {
    const w = curveCanvas.width, h = curveCanvas.height, L = 34, B = 20, R = 8, Tm = 8;
    cctx.clearRect(0, 0, w, h);
    cctx.strokeStyle = "#bbb"; cctx.lineWidth = 1; cctx.font = "11px system-ui, sans-serif"; cctx.fillStyle = "#667";
    const c = S.curve, tmax = Math.max(c.length ? c[c.length - 2] : 0, 10);
    for (const level of [0, 0.5, 0.9, 1]) {
      const y = Tm + (1 - level) * (h - Tm - B);
      cctx.beginPath(); cctx.moveTo(L, y); cctx.lineTo(w - R, y); cctx.stroke();
      cctx.fillText(`${Math.round(level * 100)}%`, 2, y + 4);
    }
    cctx.fillText("0 s", L, h - 5);
    const label = `${tmax.toFixed(0)} s`;
    cctx.fillText(label, w - R - cctx.measureText(label).width, h - 5);
    if (c.length < 2) return;
    cctx.strokeStyle = "#1e5adc"; cctx.lineWidth = 2; cctx.beginPath();
    for (let i = 0; i < c.length; i += 2) {
      const x = L + (c[i] / tmax) * (w - L - R), y = Tm + (1 - c[i + 1]) * (h - Tm - B);
      if (i === 0) cctx.moveTo(x, y); else cctx.lineTo(x, y);
    }
    cctx.stroke();
  }

  function fmtTime(t) {
    const m = Math.floor(t / 60), s = t - 60 * m;
    return m ? `${m} min ${s.toFixed(1).padStart(4, "0")} s` : `${s.toFixed(1)} s`;
  }

  function pathLength() {
    let d = 0;
    for (let i = 2; i < S.path.length; i += 2) d += Math.hypot(S.path[i] - S.path[i - 2], S.path[i + 1] - S.path[i - 1]);
    return d;
  }

  let pending = Promise.resolve();
  async function handle(msg) {
    if (msg.meta && msg.meta.geo) {
      S.meta = msg.meta; S.path = []; S.curve = []; S.mapCanvas = S.potCanvas = null; S.overlays = {};
      $("title").textContent = msg.meta.title || "robotexp live view";
      $("run").textContent = msg.meta.run || "-";
      fitCanvas(); bgDirty = true; $("scale").textContent = scaleText(msg.meta.geo);
    }
    S.t = msg.t; S.status = msg.status || {}; S.controls = msg.controls || [];
    if (msg.pose) S.pose = msg.pose;
    if (msg.laser) S.laser = msg.laser;
    if (msg.path && msg.path.length) {
      if (msg.path_from * 2 < S.path.length) bgDirty = true;
      S.path.length = msg.path_from * 2; S.path.push(...msg.path);
    }
    if (msg.curve && msg.curve.length) { S.curve.length = msg.curve_from * 2; S.curve.push(...msg.curve); }
    if (msg.map) {
      const bytes = await inflate(msg.map.data);
      S.mapCanvas = layerCanvas(bytes, msg.map.rows, msg.map.cols, (v) => CLASS_RGBA[v] || CLASS_RGBA[0]);
      S.mapVersion += 1; canvas.dataset.mapVersion = String(S.mapVersion); bgDirty = true;
    }
    if (msg.overlays) {
      S.overlays = msg.overlays; bgDirty = true;
      const pot = msg.overlays.potential;
      if (pot) {
        const bytes = await inflate(pot.data);
        S.potCanvas = layerCanvas(bytes, pot.rows, pot.cols,
          (v) => (v === 255 ? [0, 0, 0, 0] : [...viridis(v / 254), 255]));
      } else S.potCanvas = null;
      const extra = [];
      if (pot) extra.push("potential (log scale): goal purple → far yellow");
      if (msg.overlays.points) extra.push(...Object.keys(msg.overlays.points));
      if (msg.overlays.circles) extra.push(...Object.keys(msg.overlays.circles));
      if (msg.overlays.polygons) extra.push(...Object.keys(msg.overlays.polygons));
      if (msg.overlays.lines) extra.push(...Object.keys(msg.overlays.lines));
      $("legend-extra").textContent = extra.join(" · ");
    }
    if (msg.speedup != null) $("speedup").textContent = `${msg.speedup.toFixed(1)}×`;
    $("coverage").textContent = msg.coverage == null ? (S.meta && S.meta.truth === false ? "n/a" : "-")
                                                     : `${(msg.coverage * 100).toFixed(1)} %`;
    $("t").textContent = fmtTime(msg.t);
    $("pathlen").textContent = `${pathLength().toFixed(1)} m`;
    if (S.pose) $("pose").textContent =
      `${(S.pose[0]).toFixed(2)}, ${(S.pose[1]).toFixed(2)} m, ${(S.pose[2] * 180 / Math.PI).toFixed(0)}°`;
    showStatus();
    document.body.dataset.t = String(msg.t);
    if (!drawPending) { drawPending = true; requestAnimationFrame(() => { drawPending = false; draw(); drawCurve(); }); }
  }
  let drawPending = false;

  function showStatus() {
    const st = S.status.state || "waiting", ended = st === "ended";
    document.body.dataset.state = st;
    $("state").textContent = st;
    $("reason").textContent = S.status.reason || "";
    $("pause").textContent = st === "paused" ? "Resume" : "Pause";
    $("pause").disabled = ended || !S.controls.includes("pause");
    $("step").disabled = ended || !S.controls.includes("step");
    $("stop").disabled = ended || !S.controls.includes("stop");
    $("speedbox").style.display = S.controls.includes("speed") ? "" : "none";
    $("speed").disabled = ended;
    const sp = S.status.speed == null ? "max" : String(S.status.speed);
    if (document.activeElement !== $("speed")) {
      if (![...$("speed").options].some((o) => o.value === sp)) $("speed").add(new Option(`${sp}x`, sp));
      $("speed").value = sp;
    }
  }

  let ws = null;
  function send(obj) { if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(obj)); }
  function connect() {
    ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
    ws.onmessage = (ev) => { const msg = JSON.parse(ev.data); pending = pending.then(() => handle(msg)).catch(console.error); };
    ws.onclose = () => {
      if (S.status.state !== "ended") { document.body.dataset.state = "disconnected"; $("state").textContent = "disconnected"; }
      else $("reason").textContent = (S.status.reason || "") + " (server closed)";
      setTimeout(connect, 2000);
    };
  }
  $("pause").onclick = () => send({ cmd: S.status.state === "paused" ? "resume" : "pause" });
  $("step").onclick = () => send({ cmd: "step" });
  $("stop").onclick = () => send({ cmd: "stop" });
  $("speed").onchange = () => send({ cmd: "speed", value: $("speed").value });
  document.addEventListener("keydown", (ev) => {
    if (ev.target.tagName === "SELECT") return;
    if (ev.key === " ") { ev.preventDefault(); $("pause").click(); } else if (ev.key === "s") $("step").click();
  });
  window.addEventListener("resize", () => { fitCanvas(); bgDirty = true; draw(); });
  connect();
})();
