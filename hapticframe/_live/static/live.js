// hapticframe's live page: frames arrive over a websocket and are drawn on canvases.
// Plain JavaScript, no library, nothing fetched from elsewhere.
"use strict";

const hf = {rate: 0, frames: 0, mapDraws: 0, mapVersion: null, pathPoints: 0, forceDraws: 0,
            forceSamples: 0, probDraws: 0, lastT: 0, mode: null, status: null};
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

let frame = null, selectedMap = null, socket = null, wantedT = null;
const arrivals = [];

function $(id) { return document.getElementById(id); }

function connect() {
  socket = new WebSocket(`ws://${location.host}/ws`);
  socket.onmessage = (event) => {
    frame = JSON.parse(event.data);
    hf.frames += 1;
    arrivals.push(performance.now());
    while (arrivals.length && arrivals[0] < arrivals[arrivals.length - 1] - 2000) arrivals.shift();
    const span = (arrivals[arrivals.length - 1] - arrivals[0]) / 1000;
    hf.rate = span > 0 ? (arrivals.length - 1) / span : 0;
    draw(frame);
  };
  socket.onopen = () => { if (wantedT !== null) send(wantedT); };
  socket.onclose = () => { $("status").textContent = "disconnected"; setTimeout(connect, 1000); };
}

function send(t) {
  wantedT = t;
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify({t_s: t}));
}

// --- the world's extent and its mapping onto a canvas ------------------------------------

function extent(f) {
  const map = currentMap(f);
  if (map) {
    const [x0, y0] = map.origin_m, [dx, dy] = map.cell_m;
    return [x0, y0, x0 + map.columns * dx, y0 + map.rows * dy];
  }
  let box = null;
  for (const path of Object.values(f.paths)) {
    for (const [x, y] of path.points.flat().concat(path.current)) {
      box = box ? [Math.min(box[0], x), Math.min(box[1], y), Math.max(box[2], x),
                   Math.max(box[3], y)] : [x, y, x, y];
    }
  }
  if (!box) return [0, 0, 1, 1];
  const pad = 0.05;
  return [box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad];
}

function projector(canvas, box) {
  const w = box[2] - box[0] || 1, h = box[3] - box[1] || 1, m = 30;
  const s = Math.min((canvas.width - 2 * m) / w, (canvas.height - 2 * m) / h);
  const ox = (canvas.width - s * w) / 2, oy = (canvas.height - s * h) / 2;
  return {s, ox, oy, x: (x) => ox + (x - box[0]) * s, y: (y) => canvas.height - oy - (y - box[1]) * s};
}

function currentMap(f) {
  const ids = Object.keys(f.maps);
  if (!ids.length) return null;
  if (!ids.includes(selectedMap)) selectedMap = ids[0];
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
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(gridImage(map, field, table), P.x(box[0]), P.y(box[3]),
                  (box[2] - box[0]) * P.s, (box[3] - box[1]) * P.s);
  } else {
    ctx.fillStyle = "#777";
    ctx.fillText(map ? "no std in this map" : "no map snapshot yet", 40, 40);
  }
  ctx.strokeStyle = "#333"; ctx.lineWidth = 1;
  ctx.strokeRect(P.x(box[0]), P.y(box[3]), (box[2] - box[0]) * P.s, (box[3] - box[1]) * P.s);
  axes(ctx, P, box);
  if (map) {
    ctx.strokeStyle = "#ffffff"; ctx.lineWidth = 2;
    for (const line of map.outline) polyline(ctx, P, line, true);
  }
  if (!withPath) return;
  for (const path of Object.values(f.paths)) {
    ctx.strokeStyle = "#ff9800"; ctx.lineWidth = 1.2;
    for (const part of path.points) polyline(ctx, P, part, false);
    ctx.strokeStyle = "#e53935"; ctx.lineWidth = 3;
    polyline(ctx, P, path.current, false);
    if (path.position_m) {
      ctx.fillStyle = "#00e5ff";
      ctx.beginPath(); ctx.arc(P.x(path.position_m[0]), P.y(path.position_m[1]), 5, 0, 2 * Math.PI);
      ctx.fill(); ctx.strokeStyle = "#000"; ctx.lineWidth = 1; ctx.stroke();
    }
  }
  ctx.fillStyle = "#000";
  for (const m of f.movements) {
    if (m.halted && m.final_position_m) {
      ctx.fillRect(P.x(m.final_position_m[0]) - 4, P.y(m.final_position_m[1]) - 4, 8, 8);
    }
  }
}

function polyline(ctx, P, points, closed) {
  if (!points || points.length < 2) return;
  ctx.beginPath();
  ctx.moveTo(P.x(points[0][0]), P.y(points[0][1]));
  for (let i = 1; i < points.length; i++) ctx.lineTo(P.x(points[i][0]), P.y(points[i][1]));
  if (closed) ctx.closePath();
  ctx.stroke();
}

function axes(ctx, P, box) {
  ctx.fillStyle = "#333"; ctx.font = "11px sans-serif";
  ctx.fillText(`x ${box[0].toFixed(2)} … ${box[2].toFixed(2)} m`, P.x(box[0]), P.y(box[1]) + 14);
  ctx.save(); ctx.translate(P.x(box[0]) - 6, P.y(box[1])); ctx.rotate(-Math.PI / 2);
  ctx.fillText(`y ${box[1].toFixed(2)} … ${box[3].toFixed(2)} m`, 0, 0); ctx.restore();
}

// --- time series -------------------------------------------------------------------------

function drawSeries(canvas, series, yMax, legend) {
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const m = {l: 44, r: 10, t: 10, b: 24};
  const w = canvas.width - m.l - m.r, h = canvas.height - m.t - m.b;
  let t0 = Infinity, t1 = -Infinity, top = yMax || 0;
  for (const s of series) {
    if (!s.t.length) continue;
    t0 = Math.min(t0, s.t[0]); t1 = Math.max(t1, s.t[s.t.length - 1]);
    if (!yMax) for (const v of s.v) top = Math.max(top, v);
  }
  ctx.strokeStyle = "#999"; ctx.strokeRect(m.l, m.t, w, h);
  ctx.fillStyle = "#333"; ctx.font = "11px sans-serif";
  if (!isFinite(t0)) { ctx.fillText("no data yet", m.l + 10, m.t + 20); legend.textContent = ""; return; }
  if (t1 <= t0) t1 = t0 + 1;
  top = top > 0 ? top * (yMax ? 1 : 1.1) : 1;
  const X = (t) => m.l + (t - t0) / (t1 - t0) * w, Y = (v) => m.t + h - v / top * h;
  for (let k = 0; k <= 4; k++) {
    const v = top * k / 4;
    ctx.fillText(v.toFixed(yMax ? 2 : 1), 4, Y(v) + 4);
    ctx.strokeStyle = "#eee"; ctx.beginPath(); ctx.moveTo(m.l, Y(v)); ctx.lineTo(m.l + w, Y(v)); ctx.stroke();
  }
  ctx.fillText(`${t0.toFixed(2)} s`, m.l, canvas.height - 6);
  ctx.fillText(`${t1.toFixed(2)} s`, m.l + w - 40, canvas.height - 6);
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

function draw(f) {
  hf.mode = f.mode; hf.status = f.status; hf.lastT = f.t_s;
  $("mode").textContent = f.mode;
  $("name").textContent = f.name || "";
  $("status").textContent = f.status;
  $("time").textContent = f.t_s.toFixed(2);
  $("rate").textContent = hf.rate.toFixed(1);
  $("phase").textContent = f.phase || "–";
  $("interaction").textContent = Object.entries(f.interaction)
    .map(([cid, s]) => `${cid}: ${s.class} (${s.probability.toFixed(2)})`).join(", ") || "–";
  const paths = Object.values(f.paths);
  $("movement").textContent = paths.length ? paths.map((p) => p.movement).join(", ") : "–";

  const select = $("map-select"), ids = Object.keys(f.maps);
  if (select.options.length !== ids.length) {
    select.innerHTML = ids.map((id) => `<option>${id}</option>`).join("");
  }
  const map = currentMap(f);
  if (map) { select.value = selectedMap; $("level").textContent = map.outline_level; }
  drawWorld($("map-mean"), f, "mean", MEAN_RAMP, true);
  drawWorld($("map-std"), f, "std", STD_RAMP, false);
  if (map && map.version !== hf.mapVersion) { hf.mapVersion = map.version; hf.mapDraws += 1; }
  hf.pathPoints = paths.reduce(
    (n, p) => n + p.points.reduce((k, part) => k + part.length, 0) + p.current.length, 0);

  const forces = Object.entries(f.forces).map(([name, s]) => ({name, t: s.t_s, v: s.values}));
  drawSeries($("force"), forces, 0, $("force-legend"));
  if (f.counts.force_samples !== hf.forceSamples) {
    hf.forceSamples = f.counts.force_samples; hf.forceDraws += 1;
  }
  const probs = [];
  for (const [cid, s] of Object.entries(f.probabilities)) {
    s.classes.forEach((name, k) => probs.push({name: `${cid}: ${name}`, t: s.t_s,
                                                  v: s.values.map((row) => row[k])}));
  }
  drawSeries($("probs"), probs, 1, $("probs-legend"));
  hf.probDraws += probs.length ? 1 : 0;

  $("metrics").innerHTML = Object.entries(f.metrics).map(([k, v]) =>
    `<tr><td>${k}</td><td>${typeof v === "number" ? +v.toPrecision(5) : v}</td></tr>`).join("")
    + `<tr><td>messages (dropped)</td><td>${f.counts.messages} (${f.counts.dropped})</td></tr>`;
  $("errors").textContent = Object.entries(f.errors).map(([t, e]) => `${t}: ${e}`).join("; ");

  if (f.timeline) {
    const bar = $("timeline"), slider = $("slider");
    bar.hidden = false;
    slider.min = f.timeline.start_s; slider.max = f.timeline.end_s;
    if (document.activeElement !== slider && !playing) slider.value = f.timeline.t_s;
    $("slider-label").textContent = `${(+f.timeline.t_s).toFixed(2)} / ${f.timeline.end_s.toFixed(2)} s`;
  }
}

let playing = null;
$("slider").addEventListener("input", (e) => send(+e.target.value));
$("map-select").addEventListener("change", (e) => { selectedMap = e.target.value; if (frame) draw(frame); });
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
