// A small canvas plot of run columns against time_s: one panel per quantity (current,
// speed or position, voltage), each with its own axis, unit and legend. No library, so the
// page works on a stand network without internet and needs no build step.
"use strict";

const COLORS = ["#1565c0", "#c62828", "#2e7d32", "#ef6c00", "#6a1b9a"];
// Panel order and which columns go in each: the prefix of a run column (CONTRACT §1).
const PANELS = [
  { prefix: "current", label: "current" },
  { prefix: "velocity", label: "speed" },
  { prefix: "position", label: "position" },
  { prefix: "voltage", label: "voltage" },
];

// "current_in_A" -> "A", "velocity_rad_s" -> "rad/s".
function unitOf(name) {
  if (name.endsWith("_rad_s")) return "rad/s";
  if (name.endsWith("_rad")) return "rad";
  const last = name.split("_").pop();
  return last;
}

function niceRange(values) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) {
    if (Number.isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; }
  }
  if (!Number.isFinite(lo)) return [0, 1];
  if (lo === hi) { lo -= 1; hi += 1; }
  const pad = 0.05 * (hi - lo);
  return [lo - pad, hi + pad];
}

function fmt(v) {
  const a = Math.abs(v);
  return (a !== 0 && (a < 1e-2 || a >= 1e4)) ? v.toExponential(1) : v.toPrecision(3);
}

// Draw `columns` ({name: [values]}, with time_s) on `canvas`; returns the points drawn.
function plotColumns(canvas, columns) {
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  ctx.clearRect(0, 0, W, H);
  const time = columns.time_s || [];
  const panels = [];
  for (const p of PANELS) {
    const names = Object.keys(columns).filter((n) => n.startsWith(p.prefix));
    // speed OR position: position is the integral of speed, one of them is enough
    if (p.prefix === "position" && panels.some((q) => q.prefix === "velocity")) continue;
    if (names.length) panels.push({ ...p, names });
  }
  if (!time.length || !panels.length) {
    ctx.fillStyle = "#777";
    ctx.fillText("no samples yet", 20, 20);
    return 0;
  }
  const left = 70, right = 150, top = 8, bottom = 34, gap = 26;
  const h = (H - top - bottom - gap * (panels.length - 1)) / panels.length;
  const [t0, t1] = [time[0], time[time.length - 1] > time[0] ? time[time.length - 1] : time[0] + 1];
  const x = (t) => left + (W - left - right) * (t - t0) / (t1 - t0);
  // Thin to about one point per pixel column: the live stream may hold 10^5 samples.
  const step = Math.max(1, Math.floor(time.length / (W - left - right)));
  let drawn = 0;
  ctx.font = "11px sans-serif";
  panels.forEach((panel, k) => {
    const y0 = top + k * (h + gap);
    const all = panel.names.flatMap((n) => columns[n]);
    const [lo, hi] = niceRange(all);
    const y = (v) => y0 + h - h * (v - lo) / (hi - lo);
    ctx.strokeStyle = "#999"; ctx.lineWidth = 1;
    ctx.strokeRect(left, y0, W - left - right, h);
    ctx.fillStyle = "#333"; ctx.textAlign = "right";
    ctx.fillText(fmt(hi), left - 4, y0 + 10);
    ctx.fillText(fmt(lo), left - 4, y0 + h);
    ctx.save();
    ctx.translate(14, y0 + h / 2); ctx.rotate(-Math.PI / 2); ctx.textAlign = "center";
    ctx.fillText(`${panel.label}, ${unitOf(panel.names[0])}`, 0, 0);
    ctx.restore();
    panel.names.forEach((name, j) => {
      const values = columns[name];
      ctx.strokeStyle = COLORS[j % COLORS.length]; ctx.lineWidth = 1.2;
      ctx.beginPath();
      let pen = false;
      for (let i = 0; i < values.length; i += step) {
        if (!Number.isFinite(values[i])) { pen = false; continue; }
        const px = x(time[i]), py = y(values[i]);
        if (pen) ctx.lineTo(px, py); else ctx.moveTo(px, py);
        pen = true; drawn++;
      }
      ctx.stroke();
      ctx.fillStyle = COLORS[j % COLORS.length]; ctx.textAlign = "left";
      ctx.fillText(name, W - right + 8, y0 + 12 + 14 * j);  // the legend
    });
  });
  ctx.fillStyle = "#333"; ctx.textAlign = "left";
  ctx.fillText(fmt(t0), left, H - bottom + 14);
  ctx.textAlign = "right";
  ctx.fillText(fmt(t1), W - right, H - bottom + 14);
  ctx.textAlign = "center";
  ctx.fillText("time, s", left + (W - left - right) / 2, H - 6);
  canvas.dataset.points = String(drawn);
  canvas.dataset.samples = String(time.length);  // drawn thinned; this is what it holds
  return drawn;
}
