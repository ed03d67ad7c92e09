// hapticframe's live page: frames arrive over a websocket and are drawn on canvases.
// Plain JavaScript, no library, nothing fetched from elsewhere.
"use strict";

const hf = {rate: 0, frames: 0, mapDraws: 0, mapVersion: null, pathPoints: 0, forceDraws: 0,
            forceSamples: 0, probDraws: 0, lastT: 0, mode: null, status: null, reason: "",
            objectsDrawn: 0, regionDrawn: false, outlinePoints: 0, map: null};
window.hfLive = hf;  // what a test (or a curious person) can read

const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"];
// viridis at 6 stops, interpolated (the mean), and a dark-to-bright ramp (the std)
const VIRIDIS = [[68, 1, 84], [65, 68, 135], [42, 120, 142], [34, 168, 132],
                 [122, 209, 81], [253, 231, 37]];
const MAGMA = [[0, 0, 4], [59, 15, 112], [140, 41, 129], [222, 73, 104], [254, 159, 109],
               [252, 253, 191]];

function ramp(stops) {
  const table = new Uint8ClampedArray(256 * 3);
  for (let i = 0; i < 256; i++) {
    const x = i / 255 * (stops.length - 1), k = Math.min(Math.floor(x), stops.length - 2);
    const f = x - k;
    for (let c = 0; c < 3; c++) table[i * 3 + c] = stops[k][c] * (1 - f) + stops[k + 1][c] * f;
  }
  return table;
}
const MEAN_RAMP = ramp(VIRIDIS), STD_RAMP = ramp(MAGMA);
const TRUTH = "#00e676", OUTLINE = "#ffffff", REGION = "#9e9e9e";
const STATUS_TEXT = {ok: "finished", running: "running", failed: "failed",
                     interrupted: "interrupted", disconnected: "disconnected",
                     connecting: "connecting", recording: "recorded run",
                     "recording (end)": "recorded run (end)"};

let frame = null, selectedMap = null, pickedMap = null, socket = null, wantedT = null;
const arrivals = [];

function $(id) { return document.getElementById(id); }

// The session's token, from the address the command printed: the server answers no one
// without it, and the websocket carries it on.
const TOKEN = new URLSearchParams(location.search).get("token") || "";

function connect() {
  socket = new WebSocket(`ws://${location.host}/ws?token=${encodeURIComponent(TOKEN)}`);
  socket.onmessage = (event) => {
    const message = JSON.parse(event.data);
    if (message.error) {  // the server refused what this page asked (a time out of range)
      hf.refusals = (hf.refusals || 0) + 1;
      $("errors").textContent = `The server refused: ${message.error}`;
      return;
    }
    frame = message;
    hf.frames += 1;
    arrivals.push(performance.now());
    while (arrivals.length && arrivals[0] < arrivals[arrivals.length - 1] - 2000) arrivals.shift();
    const span = (arrivals[arrivals.length - 1] - arrivals[0]) / 1000;
    hf.rate = span > 0 ? (arrivals.length - 1) / span : 0;
    draw(frame);
  };
  socket.onopen = () => { if (wantedT !== null) send(wantedT); };
  socket.onclose = () => {
    // The command has stopped (or the network went): keep the last picture, say so.
    showStatus("disconnected", frame ? `The page lost its server (the command has stopped). `
      + `The last picture stays${frame.status ? ` (the run: ${STATUS_TEXT[frame.status] || frame.status})` : ""}; `
      + "reconnecting every second." : "No server yet; reconnecting every second.");
    setTimeout(connect, 1000);
  };
}

function send(t) {
  wantedT = t;
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify({t_s: t}));
}

// --- the world's extent and its mapping onto a canvas ------------------------------------

function grow(box, x, y) {
  return box ? [Math.min(box[0], x), Math.min(box[1], y), Math.max(box[2], x), Math.max(box[3], y)]
             : [x, y, x, y];
}

function extent(f) {
  // The region (from /scene) and the map's grid; the path when neither is known yet.
  let box = null;
  if (f.scene && f.scene.region) for (const [x, y] of f.scene.region) box = grow(box, x, y);
  const map = currentMap(f);
  if (map) {
    const [x0, y0] = map.origin_m, [dx, dy] = map.cell_m;
    box = grow(grow(box, x0, y0), x0 + map.columns * dx, y0 + map.rows * dy);
  }
  if (box) return box;
  for (const path of Object.values(f.paths)) {
    for (const [x, y] of path.points.flat().concat(path.current)) box = grow(box, x, y);
  }
  if (!box) return [0, 0, 1, 1];
  const pad = 0.05;
  return [box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad];
}

function projector(canvas, box) {
  const w = box[2] - box[0] || 1, h = box[3] - box[1] || 1, ml = 52, mb = 40, mr = 14, mt = 14;
  const s = Math.min((canvas.width - ml - mr) / w, (canvas.height - mt - mb) / h);
  const ox = ml + (canvas.width - ml - mr - s * w) / 2;
  const oy = mb + (canvas.height - mt - mb - s * h) / 2;
  return {s, ox, oy, x: (x) => ox + (x - box[0]) * s, y: (y) => canvas.height - oy - (y - box[1]) * s};
}

function currentMap(f) {
  const ids = Object.keys(f.maps);
  if (!ids.length) return null;
  // The person's pick; else the map the run scores; else the first.
  selectedMap = ids.includes(pickedMap) ? pickedMap
    : ids.includes(f.preferred_map) ? f.preferred_map : ids[0];
  return f.maps[selectedMap];
}

function decode(b64) {
  const text = atob(b64), out = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
  return out;
}

function gridImage(map, field, table) {
  const cells = decode(map[field]), image = new ImageData(map.columns, map.rows);
  for (let r = 0; r < map.rows; r++) {
    const row = map.rows - 1 - r;  // row 0 is the lowest y: the image's bottom
    for (let c = 0; c < map.columns; c++) {
      const v = cells[r * map.columns + c], p = (row * map.columns + c) * 4;
      image.data[p] = table[v * 3]; image.data[p + 1] = table[v * 3 + 1];
      image.data[p + 2] = table[v * 3 + 2]; image.data[p + 3] = 255;
    }
  }
  const off = document.createElement("canvas");
  off.width = map.columns; off.height = map.rows;
  off.getContext("2d").putImageData(image, 0, 0);
  return off;
}

function drawWorld(canvas, f, field, table, withPath) {
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const box = extent(f), P = projector(canvas, box);
  const map = currentMap(f);
  if (map && map[field]) {
    const [x0, y0] = map.origin_m, [dx, dy] = map.cell_m;
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(gridImage(map, field, table), P.x(x0), P.y(y0 + map.rows * dy),
                  map.columns * dx * P.s, map.rows * dy * P.s);
  } else {
    ctx.fillStyle = "#777"; ctx.font = "13px sans-serif";
    ctx.fillText(map ? "this map has no std" : "no map snapshot yet", P.x(box[0]) + 10,
                 P.y(box[3]) + 20);
  }
  axes(ctx, P, box);
  const region = f.scene && f.scene.region;
  if (region) {
    ctx.save(); ctx.setLineDash([6, 4]); ctx.strokeStyle = REGION; ctx.lineWidth = 2;
    polyline(ctx, P, region, true); ctx.restore();
  }
  let objects = 0;
  for (const obj of (f.scene ? f.scene.objects : [])) {
    haloLine(ctx, P, obj.points, true, TRUTH, 2.5); objects += 1;
  }
  let outlinePoints = 0;
  if (map) {
    for (const line of map.outline) { haloLine(ctx, P, line, true, OUTLINE, 2.5); outlinePoints += line.length; }
  }
  if (!withPath) return;
  hf.objectsDrawn = objects; hf.regionDrawn = !!region; hf.outlinePoints = outlinePoints;
  for (const path of Object.values(f.paths)) {
    ctx.strokeStyle = "#ff9800"; ctx.lineWidth = 2;
    for (const part of path.points) polyline(ctx, P, part, false);
    ctx.strokeStyle = "#e53935"; ctx.lineWidth = 3;
    polyline(ctx, P, path.current, false);
  }
  for (const m of f.movements) {
    if (m.halted && m.final_position_m) {
      ctx.fillStyle = "#fff";
      ctx.fillRect(P.x(m.final_position_m[0]) - 5, P.y(m.final_position_m[1]) - 5, 10, 10);
      ctx.fillStyle = "#000";
      ctx.fillRect(P.x(m.final_position_m[0]) - 4, P.y(m.final_position_m[1]) - 4, 8, 8);
    }
  }
  for (const path of Object.values(f.paths)) {  // the fingertip on top of everything
    if (!path.position_m) continue;
    ctx.fillStyle = "#00e5ff";
    ctx.beginPath(); ctx.arc(P.x(path.position_m[0]), P.y(path.position_m[1]), 6, 0, 2 * Math.PI);
    ctx.fill(); ctx.strokeStyle = "#000"; ctx.lineWidth = 1.5; ctx.stroke();
  }
}

function haloLine(ctx, P, points, closed, colour, width) {
  // A dark halo under the line: it stays visible over every colour of the map.
  ctx.strokeStyle = "rgba(0,0,0,0.85)"; ctx.lineWidth = width + 2.5;
  polyline(ctx, P, points, closed);
  ctx.strokeStyle = colour; ctx.lineWidth = width;
  polyline(ctx, P, points, closed);
}

function polyline(ctx, P, points, closed) {
  if (!points || points.length < 2) return;
  ctx.beginPath();
  ctx.moveTo(P.x(points[0][0]), P.y(points[0][1]));
  for (let i = 1; i < points.length; i++) ctx.lineTo(P.x(points[i][0]), P.y(points[i][1]));
  if (closed) ctx.closePath();
  ctx.stroke();
}

function niceStep(span, most) {
  const raw = span / most, p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const k of [1, 2, 2.5, 5, 10]) if (k * p >= raw) return k * p;
  return 10 * p;
}

function ticks(lo, hi, most) {
  const step = niceStep(hi - lo || 1, most), out = [];
  for (let v = Math.ceil(lo / step - 1e-9) * step; v <= hi + 1e-9; v += step) out.push(v);
  // As many decimals as the step has (0.25 needs two, 0.2 one).
  const decimals = (+step.toPrecision(6)).toString().split(".")[1];
  return {step, values: out, digits: decimals ? Math.min(decimals.length, 6) : 0};
}

function axes(ctx, P, box) {
  ctx.save();
  ctx.strokeStyle = "#333"; ctx.lineWidth = 1; ctx.fillStyle = "#333"; ctx.font = "11px sans-serif";
  const left = P.x(box[0]), bottom = P.y(box[1]), right = P.x(box[2]), top = P.y(box[3]);
  ctx.strokeRect(left, top, right - left, bottom - top);
  const tx = ticks(box[0], box[2], 8), ty = ticks(box[1], box[3], 6);
  ctx.textAlign = "center";
  for (const v of tx.values) {
    ctx.beginPath(); ctx.moveTo(P.x(v), bottom); ctx.lineTo(P.x(v), bottom + 4); ctx.stroke();
    ctx.fillText(v.toFixed(tx.digits), P.x(v), bottom + 15);
  }
  ctx.fillText("x (m)", (left + right) / 2, bottom + 30);
  ctx.textAlign = "right";
  for (const v of ty.values) {
    ctx.beginPath(); ctx.moveTo(left, P.y(v)); ctx.lineTo(left - 4, P.y(v)); ctx.stroke();
    ctx.fillText(v.toFixed(ty.digits), left - 6, P.y(v) + 4);
  }
  ctx.translate(left - 38, (top + bottom) / 2); ctx.rotate(-Math.PI / 2);
  ctx.textAlign = "center"; ctx.fillText("y (m)", 0, 0);
  ctx.restore();
}

// --- time series -------------------------------------------------------------------------

function drawSeries(canvas, series, yMax, legend, yLabel) {
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const m = {l: 56, r: 10, t: 10, b: 36};
  const w = canvas.width - m.l - m.r, h = canvas.height - m.t - m.b;
  let t0 = Infinity, t1 = -Infinity, top = yMax || 0;
  for (const s of series) {
    if (!s.t.length) continue;
    t0 = Math.min(t0, s.t[0]); t1 = Math.max(t1, s.t[s.t.length - 1]);
    if (!yMax) for (const v of s.v) top = Math.max(top, v);
  }
  ctx.strokeStyle = "#999"; ctx.strokeRect(m.l, m.t, w, h);
  ctx.fillStyle = "#333"; ctx.font = "11px sans-serif";
  if (!isFinite(t0)) {
    ctx.fillText(legend.id === "force-legend" ? "no force channel in newtons yet" : "no classifier output yet",
                 m.l + 10, m.t + 20);
    legend.textContent = ""; return;
  }
  if (t1 <= t0) t1 = t0 + 1;
  top = top > 0 ? top * (yMax ? 1 : 1.1) : 1;
  const X = (t) => m.l + (t - t0) / (t1 - t0) * w, Y = (v) => m.t + h - v / top * h;
  const ty = ticks(0, top, 4);
  ctx.textAlign = "right";
  for (const v of ty.values) {
    ctx.fillText(v.toFixed(ty.digits), m.l - 6, Y(v) + 4);
    ctx.strokeStyle = "#eee"; ctx.beginPath(); ctx.moveTo(m.l, Y(v)); ctx.lineTo(m.l + w, Y(v)); ctx.stroke();
  }
  const tt = ticks(t0, t1, 8);
  ctx.textAlign = "center";
  for (const t of tt.values) {
    ctx.strokeStyle = "#999"; ctx.beginPath(); ctx.moveTo(X(t), m.t + h); ctx.lineTo(X(t), m.t + h + 4); ctx.stroke();
    ctx.fillText(t.toFixed(tt.digits), X(t), m.t + h + 15);
  }
  ctx.fillText("model time (s)", m.l + w / 2, canvas.height - 4);
  ctx.save(); ctx.translate(14, m.t + h / 2); ctx.rotate(-Math.PI / 2); ctx.fillText(yLabel, 0, 0);
  ctx.restore(); ctx.textAlign = "left";
  legend.innerHTML = "";
  series.forEach((s, i) => {
    ctx.strokeStyle = COLORS[i % COLORS.length]; ctx.lineWidth = 1.5; ctx.beginPath();
    s.t.forEach((t, j) => (j ? ctx.lineTo(X(t), Y(s.v[j])) : ctx.moveTo(X(t), Y(s.v[j]))));
    ctx.stroke();
    const item = document.createElement("span");
    item.innerHTML = `<span class="swatch" style="background:${COLORS[i % COLORS.length]}"></span>${s.name}`;
    legend.appendChild(item);
  });
}

// --- the frame ---------------------------------------------------------------------------

function showStatus(status, message) {
  const badge = $("status"), banner = $("banner");
  badge.textContent = STATUS_TEXT[status] || status;
  badge.dataset.status = status;
  banner.hidden = !message;
  banner.textContent = message || "";
  banner.dataset.status = status;
  hf.status = status;
}

function statusMessage(f) {
  // What a person at the page needs to know about how the run stands.
  if (f.status === "failed") {
    return `The run failed: ${f.reason || "see the terminal"}. The page shows its last picture `
      + "until Ctrl-C in the terminal.";
  }
  if (f.status === "interrupted") {
    return `The run was interrupted (${f.reason || "signal"}). The page shows its last picture `
      + "until Ctrl-C in the terminal.";
  }
  if (f.status === "ok" && f.mode === "live") {
    return "The run has finished: final metrics below. The page stays up until Ctrl-C in the terminal.";
  }
  return "";
}

function fmt(v) {
  if (typeof v === "number") return Number.isInteger(v) ? String(v) : String(+v.toPrecision(5));
  if (v === null || v === undefined) return "–";
  return String(v);
}

function draw(f) {
  hf.mode = f.mode; hf.lastT = f.t_s; hf.reason = f.reason || "";
  $("mode").textContent = f.mode === "view" ? "view" : "live";
  $("name").textContent = f.name || "";
  showStatus(f.status, statusMessage(f));
  $("time").textContent = f.t_s.toFixed(2);
  $("rate").textContent = hf.rate.toFixed(1);
  $("phase").textContent = f.phase || "–";
  // The classifier's id only when there are several (it often shares a class's name).
  const several = Object.keys(f.interaction).length > 1;
  $("interaction").textContent = Object.entries(f.interaction)
    .map(([cid, s]) => `${several ? `${cid}: ` : ""}${s.class} (P = ${s.probability.toFixed(2)})`)
    .join(", ") || "–";
  const paths = Object.values(f.paths);
  $("movement").textContent = paths.length ? paths.map((p) => `#${p.movement + 1}`).join(", ") : "–";

  const select = $("map-select"), ids = Object.keys(f.maps);
  const labels = ids.map((id) => (id === f.preferred_map ? `${id} (evaluated)` : id));
  if (select.options.length !== ids.length
      || labels.some((label, i) => select.options[i].textContent !== label)) {
    select.innerHTML = ids.map((id, i) => `<option value="${id}">${labels[i]}</option>`).join("");
  }
  const map = currentMap(f);
  if (map) {
    select.value = selectedMap;
    for (const el of document.querySelectorAll(".level")) el.textContent = map.outline_level;
    // The scale runs to the map's largest std, as the report's figure does.
    $("std-top").textContent = `${+map.std_scale.toPrecision(2)} (the map's largest)`;
    const source = {recording: "", grid: ", outline from the grid",
                    none: `, nothing above P = ${map.outline_level} yet`}[map.outline_source] || "";
    $("map-note").textContent = `snapshot at ${map.t_s.toFixed(2)} s${source}`;
  } else {
    $("map-note").textContent = "waiting for the first map snapshot";
  }
  drawWorld($("map-mean"), f, "mean", MEAN_RAMP, true);
  drawWorld($("map-std"), f, "std", STD_RAMP, false);
  if (map && map.version !== hf.mapVersion) { hf.mapVersion = map.version; hf.mapDraws += 1; }
  hf.map = selectedMap;
  hf.pathPoints = paths.reduce(
    (n, p) => n + p.points.reduce((k, part) => k + part.length, 0) + p.current.length, 0);

  const forces = Object.entries(f.forces).map(([name, s]) => ({name, t: s.t_s, v: s.values}));
  drawSeries($("force"), forces, 0, $("force-legend"), "|F| (N)");
  if (f.counts.force_samples !== hf.forceSamples) {
    hf.forceSamples = f.counts.force_samples; hf.forceDraws += 1;
  }
  const probs = [];
  const manyClassifiers = Object.keys(f.probabilities).length > 1;
  for (const [cid, s] of Object.entries(f.probabilities)) {
    s.classes.forEach((name, k) => probs.push({name: manyClassifiers ? `${cid}: ${name}` : name, t: s.t_s,
                                                  v: s.values.map((row) => row[k])}));
  }
  drawSeries($("probs"), probs, 1, $("probs-legend"), "probability");
  hf.probDraws += probs.length ? 1 : 0;

  const final = f.status === "ok" || f.status === "recording (end)";
  $("metrics-note").textContent = final ? "(the run's final metrics included)"
    : "(counted from what the page has seen)";
  $("metrics").innerHTML = Object.entries(f.metrics).map(([k, v]) =>
    `<div><span>${k}</span><b>${fmt(v)}</b></div>`).join("")
    + `<div><span>messages seen (dropped)</span><b>${f.counts.messages} (${f.counts.dropped})</b></div>`;
  $("errors").textContent = Object.entries(f.errors).map(([t, e]) => `${t}: ${e}`).join("; ");

  if (f.timeline) {
    const bar = $("timeline"), slider = $("slider");
    bar.hidden = false;
    slider.min = f.timeline.start_s; slider.max = f.timeline.end_s;
    if (document.activeElement !== slider && !playing) slider.value = f.timeline.t_s;
    $("slider-label").textContent = `${(+f.timeline.t_s).toFixed(2)} / ${f.timeline.end_s.toFixed(2)} s`;
  }
}

function colourBar(id, table) {
  const stops = [];
  for (let i = 0; i <= 10; i++) {
    const k = Math.round(i * 25.5) * 3;
    stops.push(`rgb(${table[k]},${table[k + 1]},${table[k + 2]}) ${i * 10}%`);
  }
  $(id).style.background = `linear-gradient(to right, ${stops.join(", ")})`;
}
colourBar("mean-bar", MEAN_RAMP);
colourBar("std-bar", STD_RAMP);

let playing = null;
$("slider").addEventListener("input", (e) => send(+e.target.value));
$("map-select").addEventListener("change", (e) => { pickedMap = e.target.value; if (frame) draw(frame); });
$("play").addEventListener("click", () => {
  const slider = $("slider");
  if (playing) { clearInterval(playing); playing = null; $("play").textContent = "play"; return; }
  if (+slider.value >= +slider.max) slider.value = slider.min;
  $("play").textContent = "pause";
  playing = setInterval(() => {  // 5x model time, at 10 frames a second
    const next = Math.min(+slider.value + 0.5, +slider.max);
    slider.value = next; send(next);
    if (next >= +slider.max) { clearInterval(playing); playing = null; $("play").textContent = "play"; }
  }, 100);
});
connect();
