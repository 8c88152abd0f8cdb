// nckemu's own line plot on a canvas (no library: the machines have no internet).
// drawPlot(canvas, series, options): series = [{label, color, points: [[x, y], ...], dash, width, alpha}],
// drawn in order (the last on top); options: {xLabel, yLabel, xFormat(x) -> text, xTime: x in seconds,
// ticks on whole minutes and hours}. Returns the number of points drawn.
"use strict";

function niceStep(span, count) {
  const raw = span / Math.max(1, count);
  const power = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const factor of [1, 2, 2.5, 5, 10]) {
    if (raw <= factor * power) return factor * power;
  }
  return 10 * power;
}

// Steps of a time axis in seconds: ticks fall on round clock times (01:00:00, not 05:33:20).
const TIME_STEPS = [1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400];

function niceTimeStep(span, count) {
  const raw = span / Math.max(1, count);
  for (const step of TIME_STEPS) {
    if (raw <= step) return step;
  }
  return Math.ceil(raw / 86400) * 86400;
}

function drawPlot(canvas, series, options) {
  options = options || {};
  const ratio = window.devicePixelRatio || 1;
  const width = canvas.clientWidth || canvas.width, height = canvas.clientHeight || canvas.height;
  canvas.width = Math.round(width * ratio);
  canvas.height = Math.round(height * ratio);
  const ctx = canvas.getContext("2d");
  ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
  ctx.clearRect(0, 0, width, height);
  ctx.font = "11px sans-serif";
  const left = 58, right = 12, top = 22, bottom = 34;
  const plotW = width - left - right, plotH = height - top - bottom;
  let xMin = Infinity, xMax = -Infinity, yMin = Infinity, yMax = -Infinity, drawn = 0;
  for (const s of series) {
    for (const [x, y] of s.points) {
      if (y === null || !isFinite(y)) continue;
      xMin = Math.min(xMin, x); xMax = Math.max(xMax, x);
      yMin = Math.min(yMin, y); yMax = Math.max(yMax, y);
    }
  }
  ctx.strokeStyle = "#999";
  ctx.strokeRect(left, top, plotW, plotH);
  if (!isFinite(xMin)) {
    ctx.fillStyle = "#666";
    ctx.fillText("no data yet", left + 8, top + 16);
    return 0;
  }
  if (xMax === xMin) xMax = xMin + 1;
  if (yMax - yMin < 1e-9) { yMin -= 0.5; yMax += 0.5; }
  const pad = 0.05 * (yMax - yMin);
  yMin -= pad; yMax += pad;
  const px = x => left + (x - xMin) / (xMax - xMin) * plotW;
  const py = y => top + (1 - (y - yMin) / (yMax - yMin)) * plotH;
  // grid and tick labels
  ctx.fillStyle = "#444";
  ctx.strokeStyle = "#e4e4e4";
  const yStep = niceStep(yMax - yMin, 5);
  for (let y = Math.ceil(yMin / yStep) * yStep; y <= yMax; y += yStep) {
    ctx.beginPath(); ctx.moveTo(left, py(y)); ctx.lineTo(left + plotW, py(y)); ctx.stroke();
    const text = Math.abs(yStep) < 1 ? y.toFixed(Math.min(3, Math.ceil(-Math.log10(yStep)))) : y.toFixed(0);
    ctx.fillText(text, left - 6 - ctx.measureText(text).width, py(y) + 4);
  }
  const xStep = options.xTime ? niceTimeStep(xMax - xMin, 6) : niceStep(xMax - xMin, 6);
  const xFormat = options.xFormat || (x => x.toFixed(0));
  const xTicks = [];
  for (let x = Math.ceil(xMin / xStep) * xStep; x <= xMax; x += xStep) {
    ctx.beginPath(); ctx.moveTo(px(x), top); ctx.lineTo(px(x), top + plotH); ctx.stroke();
    const text = xFormat(x), textW = ctx.measureText(text).width;
    xTicks.push(text);
    const at = Math.min(px(x) - textW / 2, width - right - textW);  // the last label stays inside
    ctx.fillText(text, at, top + plotH + 14);
  }
  canvas.dataset.xticks = xTicks.join(" ");  // what the axis shows, for a person and for the tests
  if (options.xLabel) ctx.fillText(options.xLabel, left + plotW - ctx.measureText(options.xLabel).width, height - 4);
  if (options.yLabel) ctx.fillText(options.yLabel, 4, 12);
  // lines
  for (const s of series) {
    ctx.strokeStyle = s.color;
    ctx.lineWidth = s.width || 1.6;
    ctx.globalAlpha = s.alpha || 1;
    ctx.setLineDash(s.dash || []);
    ctx.beginPath();
    let pen = false;
    for (const [x, y] of s.points) {
      if (y === null || !isFinite(y)) { pen = false; continue; }
      if (pen) ctx.lineTo(px(x), py(y)); else ctx.moveTo(px(x), py(y));
      pen = true;
      drawn += 1;
    }
    ctx.stroke();
  }
  ctx.globalAlpha = 1;
  ctx.setLineDash([]);
  // legend
  let lx = left + 8;
  for (const s of series) {
    ctx.strokeStyle = s.color;
    ctx.lineWidth = s.width || 3;
    ctx.globalAlpha = s.alpha || 1;
    ctx.setLineDash(s.dash || []);
    ctx.beginPath(); ctx.moveTo(lx, 8); ctx.lineTo(lx + 14, 8); ctx.stroke();
    ctx.globalAlpha = 1;
    ctx.setLineDash([]);
    ctx.fillStyle = "#222";
    ctx.fillText(s.label, lx + 18, 12);
    lx += 26 + ctx.measureText(s.label).width;
  }
  return drawn;
}
