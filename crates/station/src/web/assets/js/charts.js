// The Run page's curves on a canvas (output and rate against time).
import { $, KEEP_S, state } from "./core.js";
import { word } from "./i18n.js";

// The curves' text in the page's fonts (the CJK one when the browser has none).
export const CANVAS_FONT = '11px "Noto Sans", "Noto Sans CJK SC", "Microsoft YaHei", "spinbench CJK", sans-serif';

export function draw() {
  state.dirty = false;
  const c = $("curves"), g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  g.font = CANVAS_FONT;
  const strip = 110;
  cell(g, 0, 0, c.width, strip, state.rate, word("web.plot.rate", "rate"), "deg/s", "#b00");
  // Only the slots that hold an instrument in this run.
  const slots = state.history.map((_, i) => i).filter((i) => state.serials[i] || state.history[i].length);
  const n = slots.length;
  if (!n) { g.fillStyle = "#333"; g.fillText(word("web.plot.waiting", "waiting for a run's one-second values…"), 20, strip + 30); return; }
  const cols = Math.ceil(Math.sqrt(n * c.width / (c.height - strip)));
  const rows = Math.ceil(n / cols);
  const w = c.width / cols, h = (c.height - strip) / rows;
  slots.forEach((slot, k) => {
    const t = (state.temperatures || [])[slot];
    const label = word("web.plot.slot", "slot") + " " + (slot + 1) + " " + (state.serials[slot] || "") + (t == null ? "" : "  " + t.toFixed(2) + " °C");
    cell(g, (k % cols) * w, strip + Math.floor(k / cols) * h, w, h, state.history[slot], label, "Hz", "#1d3557");
  });
}

export function cell(g, x, y, w, h, pts, label, unit, color) {
  const left = 62, bottom = 14, top = 16;
  g.strokeStyle = "#ccc"; g.strokeRect(x + 1, y + 1, w - 2, h - 2);
  g.fillStyle = "#333"; g.fillText(label, x + 4, y + 12);
  if (pts.length) {
    const now = pts[pts.length - 1][1].toFixed(4) + " " + unit;
    g.fillText(now, x + w - 6 - g.measureText(now).width, y + 12);
  }
  if (pts.length < 2) return;
  let lo = Infinity, hi = -Infinity;
  for (const p of pts) { if (p[1] < lo) lo = p[1]; if (p[1] > hi) hi = p[1]; }
  if (hi === lo) { hi += Math.max(1e-9, Math.abs(hi) * 1e-6); lo -= Math.max(1e-9, Math.abs(lo) * 1e-6); }
  const px0 = x + left, pw = w - left - 6, py0 = y + top, ph = h - top - bottom - 4;
  const t1 = pts[pts.length - 1][0], t0 = t1 - KEEP_S;
  const X = (t) => px0 + pw * (t - t0) / KEEP_S, Y = (v) => py0 + ph - ph * (v - lo) / (hi - lo);
  // Grid and the value axis: four divisions, labelled at the left in the unit.
  const span = hi - lo, decimals = Math.min(6, Math.max(0, Math.ceil(-Math.log10(span / 4)) + 1));
  g.strokeStyle = "#eee"; g.fillStyle = "#555";
  for (let k = 0; k <= 4; k++) {
    const v = lo + span * k / 4, py = Y(v);
    g.beginPath(); g.moveTo(px0, py); g.lineTo(px0 + pw, py); g.stroke();
    const t = v.toFixed(decimals); g.fillText(t, px0 - 4 - g.measureText(t).width, py + 4);
  }
  // Time axis: a line every minute, labelled in seconds ago.
  for (let ago = 0; ago <= KEEP_S; ago += 60) {
    const px = X(t1 - ago);
    g.beginPath(); g.moveTo(px, py0); g.lineTo(px, py0 + ph); g.stroke();
    if (h > 60) { const t = ago ? "−" + ago + " s" : word("web.plot.now", "now"); g.fillText(t, px - g.measureText(t).width / 2, py0 + ph + bottom); }
  }
  // Level marks: a dashed line where each level began, its label on the rate strip.
  g.save(); g.setLineDash([3, 3]); g.strokeStyle = "#9ab";
  for (const [t, text] of state.marks) {
    if (t < t0 || t > t1) continue;
    const px = X(t);
    g.beginPath(); g.moveTo(px, py0); g.lineTo(px, py0 + ph); g.stroke();
    if (unit === "deg/s") { g.fillStyle = "#246"; g.fillText(text, px + 2, py0 + 10); }
  }
  g.restore();
  g.strokeStyle = color; g.beginPath();
  pts.forEach((p, k) => {
    const px = X(p[0]), py = Y(p[1]);
    if (k === 0) g.moveTo(px, py); else g.lineTo(px, py);
  });
  g.stroke();
}
