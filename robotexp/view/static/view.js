// robotexp live view: draws the frames the server sends on /ws (see robotexp/view/feed.py).
"use strict";
(() => {
  const $ = (id) => document.getElementById(id);
  const canvas = $("map"), dyn = $("dyn"), ctx = dyn.getContext("2d");
  const curveCanvas = $("curve"), cctx = curveCanvas.getContext("2d");
  const S = { meta: null, pose: null, laser: [], path: [], curve: [], overlays: {}, status: {},
              mapVersion: 0, t: 0, controls: [], team: [] };
  // a team's robots 2, 3, ... in turn (robotexp/output/render.py TEAM_COLORS)
  const TEAM_COLOURS = ["#963cc8", "#009696", "#c83c96", "#785a1e", "#5aa014"];
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

  const CLASS_RGBA = [[205, 205, 205, 255], [255, 255, 255, 255], [0, 0, 0, 255]];

  // The view is four stacked layers of the same size on the page (#stage): #map and #pot hold one
  // pixel per cell (the browser scales them), #over the explorer's overlays and the path (redrawn when
  // the overlays change; new path segments are added as they come), #dyn what moves (laser, robot),
  // all a frame redraws. A map update paints only its changed tiles (robotexp/view/feed.py encode_tiles).
  const mapx = canvas.getContext("2d"), pot = $("pot"), potx = pot.getContext("2d");
  const over = $("over"), ox = over.getContext("2d");
  let overDirty = true, overPath = 0, mapImg = null;

  function sizeLayers() {
    const g = S.meta.geo;
    for (const c of [canvas, pot]) { if (c.width !== g.cols || c.height !== g.rows) { c.width = g.cols; c.height = g.rows; } }
    mapImg = mapx.createImageData(g.cols, g.rows);
    for (let i = 0; i < mapImg.data.length; i += 4) {
      mapImg.data[i] = mapImg.data[i + 1] = mapImg.data[i + 2] = 205; mapImg.data[i + 3] = 255;
    }
    mapx.putImageData(mapImg, 0, 0);
    potx.clearRect(0, 0, pot.width, pot.height); pot.hidden = true;
  }

  async function paintTiles(m) {
    const bytes = await inflate(m.data), rows = m.rows, cols = m.cols, T = m.tile;
    if (!mapImg || mapImg.width !== cols || mapImg.height !== rows) return;
    const d = mapImg.data;
    let at = 0;
    for (let k = 0; k < m.tiles.length; k += 2) {
      const r0 = m.tiles[k] * T, c0 = m.tiles[k + 1] * T, h = Math.min(T, rows - r0), w = Math.min(T, cols - c0);
      for (let r = r0; r < r0 + h; r++) {
        let o = ((rows - 1 - r) * cols + c0) * 4;
        for (let c = 0; c < w; c++, o += 4) {
          const rgba = CLASS_RGBA[bytes[at++]] || CLASS_RGBA[0];
          d[o] = rgba[0]; d[o + 1] = rgba[1]; d[o + 2] = rgba[2];
        }
      }
    }
    mapx.putImageData(mapImg, 0, 0);
  }

  async function paintPotential(p) {
    if (!p) { pot.hidden = true; return; }
    const bytes = await inflate(p.data), rows = p.rows, cols = p.cols;
    if (pot.width !== cols || pot.height !== rows) return;
    const img = potx.createImageData(cols, rows);
    for (let r = 0; r < rows; r++) {
      const dst = (rows - 1 - r) * cols;
      for (let c = 0; c < cols; c++) {
        const v = bytes[r * cols + c], o = (dst + c) * 4;
        if (v === 255) continue;
        const rgb = viridis(v / 254);
        img.data[o] = rgb[0]; img.data[o + 1] = rgb[1]; img.data[o + 2] = rgb[2]; img.data[o + 3] = 255;
      }
    }
    potx.putImageData(img, 0, 0); pot.hidden = false;
  }

  // laser points sent packed (robotexp/view/feed.py packed_laser): int16 cm offsets from the laser
  function unpackLaser(p) {
    const b = atob(p.cm), out = new Array(b.length / 2);
    for (let i = 0; i < out.length; i++) {
      let v = b.charCodeAt(2 * i) | (b.charCodeAt(2 * i + 1) << 8);
      if (v >= 32768) v -= 65536;
      out[i] = (i % 2 ? p.y : p.x) + v / 100;
    }
    return out;
  }

  // world [m] -> layer pixels (#over, #dyn)
  function transform() {
    const g = S.meta.geo, w = g.cols * g.cell, h = g.rows * g.cell;
    const k = Math.min(over.width / w, over.height / h);
    const ox = (over.width - w * k) / 2, oy = (over.height - h * k) / 2;
    return { k, px: (x) => ox + (x - g.origin_x) * k, py: (y) => oy + h * k - (y - g.origin_y) * k, ox, oy, w, h };
  }

  // the stage takes the map's aspect: as wide as the box allows, at most 82 % of the window's height
  function fitCanvas() {
    if (!S.meta || !S.meta.geo) return;
    const g = S.meta.geo, box = $("mapbox").clientWidth - 16, aspect = g.rows / g.cols;
    let width = Math.max(300, Math.min(box, 1600)), height = width * aspect;
    const maxH = Math.max(200, window.innerHeight * 0.82);
    if (height > maxH) { height = maxH; width = height / aspect; }
    width = Math.round(width); height = Math.round(height);
    const stage = $("stage"), dpr = window.devicePixelRatio || 1;
    stage.style.width = width + "px"; stage.style.height = height + "px";
    for (const c of [over, dyn]) { c.width = Math.round(width * dpr); c.height = Math.round(height * dpr); }
    overDirty = true;
  }

  function lineWidth() { return Math.max(1, over.width / 700); }

  function drawOver() {
    const ctx = ox;
    ctx.clearRect(0, 0, over.width, over.height);
    overDirty = false; overPath = 0;
    if (!S.meta) return;
    const T = transform(), lw = lineWidth();
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
    const ctx = ox, lw = lineWidth();
    if (S.path.length < 4 || overPath >= S.path.length - 2) return;
    const from = Math.max(overPath - 2, 0);
    ctx.strokeStyle = "#1e5adc"; ctx.lineWidth = lw * 1.6; ctx.lineJoin = "round"; ctx.lineCap = "round"; ctx.beginPath();
    ctx.moveTo(T.px(S.path[from]), T.py(S.path[from + 1]));
    for (let i = from + 2; i < S.path.length; i += 2) ctx.lineTo(T.px(S.path[i]), T.py(S.path[i + 1]));
    ctx.stroke();
    overPath = S.path.length;
  }

  function draw() {
    if (!S.meta || !S.meta.geo) return;
    const T = transform(), lw = lineWidth();
    if (overDirty) drawOver(); else drawPath(T);
    ctx.clearRect(0, 0, dyn.width, dyn.height);
    if (S.pose && S.laser.length) {
      ctx.fillStyle = "#ff8c00"; const d = Math.max(2, lw * 2.2);
      for (let i = 0; i < S.laser.length; i += 2) ctx.fillRect(T.px(S.laser[i]) - d / 2, T.py(S.laser[i + 1]) - d / 2, d, d);
    }
    if (S.meta.start) drawRobot(T, S.meta.start, "rgba(40,170,60,0.8)", lw, null);
    S.team.forEach((m, i) => drawTeammate(T, m, i, lw));
    if (S.pose) drawRobot(T, S.pose, "#dc2828", lw, "rgba(220,40,40,0.25)");
  }

  function drawTeammate(T, m, i, lw) {
    const colour = TEAM_COLOURS[i % TEAM_COLOURS.length], info = (S.meta.team || [])[i] || {};
    if (m.path.length >= 4) {
      ctx.strokeStyle = colour; ctx.lineWidth = lw * 1.6; ctx.lineJoin = "round"; ctx.lineCap = "round";
      ctx.beginPath(); ctx.moveTo(T.px(m.path[0]), T.py(m.path[1]));
      for (let k = 2; k < m.path.length; k += 2) ctx.lineTo(T.px(m.path[k]), T.py(m.path[k + 1]));
      ctx.stroke();
    }
    if (m.pose) drawRobot(T, m.pose, colour, lw, colour + "40", info.radius);
  }

  // a robot's footprint (its radius, default the run's robot's) and heading; `fill`: a colour or null
  function drawRobot(T, pose, colour, lw, fill, radius) {
    const [x, y, th] = pose, r = Math.max((radius ?? S.meta.radius) * T.k, 4);
    const cx = T.px(x), cy = T.py(y);
    ctx.beginPath(); ctx.arc(cx, cy, r, 0, 2 * Math.PI);
    if (fill) { ctx.fillStyle = fill; ctx.fill(); }
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
    if (msg.type === "refused") { $("reason").textContent = `refused: ${msg.reason}`; return; }
    if (msg.meta && msg.meta.kind === "campaign") { S.meta = msg.meta; return campaign(msg, true); }
    if (S.meta && S.meta.kind === "campaign") return campaign(msg, false);
    if (msg.meta && msg.meta.geo) {
      S.meta = msg.meta; S.path = []; S.curve = []; S.overlays = {}; S.team = [];
      $("title").textContent = msg.meta.title || "robotexp live view";
      $("run").textContent = msg.meta.run || "-";
      sizeLayers(); fitCanvas(); $("scale").textContent = scaleText(msg.meta.geo);
      if (msg.meta.duration != null) {
        $("seek").max = String(msg.meta.duration); $("seektime").max = String(msg.meta.duration);
        $("duration").textContent = `of ${fmtTime(msg.meta.duration)}`;
      }
    }
    S.t = msg.t; S.status = msg.status || {}; S.controls = msg.controls || [];
    if (msg.pose) S.pose = msg.pose;
    if (msg.laser) S.laser = Array.isArray(msg.laser) ? msg.laser : unpackLaser(msg.laser);
    if (msg.path) {
      if (msg.path_from * 2 < S.path.length) overDirty = true;
      S.path.length = msg.path_from * 2; for (const v of msg.path) S.path.push(v);
    }
    if (msg.curve) { S.curve.length = msg.curve_from * 2; for (const v of msg.curve) S.curve.push(v); }
    if (msg.team) msg.team.forEach((m, i) => {
      const mine = S.team[i] || (S.team[i] = { pose: null, path: [] });
      if (m.pose) mine.pose = m.pose;
      mine.path.length = m.path_from * 2; for (const v of m.path) mine.path.push(v);
    });
    document.body.dataset.robots = String(S.team.length + 1);
    if (msg.map) {
      await paintTiles(msg.map);
      S.mapVersion += 1; canvas.dataset.mapVersion = String(S.mapVersion);
    }
    if (msg.overlays) {
      S.overlays = msg.overlays; overDirty = true;
      const pot = msg.overlays.potential;
      await paintPotential(pot);
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
    if (!seeking) $("seek").value = String(msg.t);
    if (document.activeElement !== $("seektime")) $("seektime").value = msg.t.toFixed(1);
    $("pathlen").textContent = `${pathLength().toFixed(1)} m`;
    if (S.pose) $("pose").textContent =
      `${(S.pose[0]).toFixed(2)}, ${(S.pose[1]).toFixed(2)} m, ${(S.pose[2] * 180 / Math.PI).toFixed(0)}°`;
    showStatus();
    document.body.dataset.t = String(msg.t);
    if (!drawPending) { drawPending = true; requestAnimationFrame(() => { drawPending = false; draw(); drawCurve(); }); }
  }
  let drawPending = false;

  // a campaign: runs done of total, the time so far, a row per finished run
  function campaign(msg, fresh) {
    if (fresh) {
      $("title").textContent = msg.meta.title; $("run").textContent = msg.meta.run;
      $("stage").hidden = true; $("legend").hidden = true; $("campaign").hidden = false;
      $("controls").hidden = true; $("poserow").hidden = true; $("curvebox").hidden = true;
      $("runs").tBodies[0].innerHTML = "";
      const th = document.querySelectorAll("#stats th");
      th[0].textContent = "elapsed"; th[1].textContent = "runs done"; th[2].textContent = "mean coverage";
      th[3].textContent = "jobs"; $("pathlen").textContent = String(msg.meta.jobs);
    }
    S.status = msg.status || {}; S.controls = msg.controls || [];
    const body = $("runs").tBodies[0];
    if (msg.rows && msg.rows.length) {
      while (body.rows.length > msg.rows_from) body.deleteRow(-1);
      for (const r of msg.rows) {
        const tr = body.insertRow();
        if (!r.completed) tr.className = "incomplete";
        const cells = [r.run, r.world, r.method, r.pose ?? "",
          r.coverage == null ? "n/a" : `${(r.coverage * 100).toFixed(1)} %`, `${r.path_m.toFixed(1)} m`,
          `${r.robot_time_s.toFixed(0)} s`, r.reason];
        cells.forEach((text, i) => { const td = tr.insertCell(); td.textContent = text; if (i >= 4 && i <= 6) td.className = "num"; });
      }
    }
    const done = S.status.done || 0, total = S.status.total || 0;
    $("cfill").style.width = total ? `${(100 * done / total).toFixed(1)}%` : "0";
    $("t").textContent = fmtTime(msg.t);
    $("speedup").textContent = `${done} / ${total}`;
    $("coverage").textContent = msg.coverage == null ? "-" : `${(msg.coverage * 100).toFixed(1)} %`;
    document.body.dataset.t = String(msg.t); document.body.dataset.done = String(done);
    showStatus();
    $("speedbox").style.display = "none";
  }

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
    $("seekbox").hidden = !S.controls.includes("seek");
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
  // seeking (a replay): the slider sends when let go, the time box on Enter or Go
  let seeking = false;
  const seekTo = (v) => { const t = Number(v); if (Number.isFinite(t)) send({ cmd: "seek", value: t }); };
  $("seek").oninput = () => { seeking = true; $("seektime").value = Number($("seek").value).toFixed(1); };
  $("seek").onchange = () => { seeking = false; seekTo($("seek").value); };
  $("seekgo").onclick = () => seekTo($("seektime").value);
  $("seektime").addEventListener("keydown", (ev) => { if (ev.key === "Enter") { ev.preventDefault(); seekTo($("seektime").value); } });
  document.addEventListener("keydown", (ev) => {
    if (ev.target.tagName === "SELECT" || ev.target.tagName === "INPUT") return;
    if (ev.key === " ") { ev.preventDefault(); $("pause").click(); } else if (ev.key === "s") $("step").click();
  });
  window.addEventListener("resize", () => { fitCanvas(); draw(); });
  connect();
})();
