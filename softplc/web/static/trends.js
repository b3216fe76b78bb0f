// softplc web monitor: the Trends tab's samples and drawing. Bits get lanes of their own
// (0/1 steps); each analog trace gets its own strip and axis, scaled to its own min..max
// over the window (shown in real units), so a 0-30 step word and a +-500,000 position
// are both readable. Loaded before app.js; uses its helpers ($, state, COLOURS) when called.
"use strict";

const TREND_KEEP = 3000;  // samples kept (10 per second: 5 minutes)
const STRIP_H = 110, LANE_H = 26, STRIP_GAP = 12;
// a bit object: %I0.1, %Q0.2, %M5, %S6, %X3, a word's bit %MW3:X4, a block's bit output
const BIT_RE = /^(%(I|Q|M|S|X)\d+(\.\d+)?|%[A-Z]+\d+:X\d+|%[A-Z]+\d+\.(Q|D|E|F|R|EN|TH0|TH1))$/;
const isBitTrend = (o) => BIT_RE.test(o) || state.trend.bits.has(o);

// one value as a number: bits come as JSON booleans or 0/1, blocks as {V: ...}
function trendValue(o, v) {
  if (typeof v === "boolean") { state.trend.bits.add(o); return v ? 1 : 0; }
  if (typeof v === "number" && isFinite(v)) return v;
  if (v && typeof v === "object" && typeof v.V === "number") return v.V;
  return null;
}

function trendSample(msg) {
  const tr = state.trend;
  if (!tr.bits) tr.bits = new Set();  // objects seen as JSON booleans
  if (tr.paused || !tr.objects.length) return;
  const row = { t: msg.status.time };
  for (const o of tr.objects) row[o] = trendValue(o, msg.values[o]);
  if (tr.data.length && row.t < tr.data[tr.data.length - 1].t) tr.data = [];  // a restart
  tr.data.push(row);
  if (tr.data.length > TREND_KEEP) tr.data.splice(0, tr.data.length - TREND_KEEP);
  if (state.tab === "trends" && !document.hidden) drawTrend();  // (shown: app.js draws it)
}

function trendRange(shown, o) {
  let lo = Infinity, hi = -Infinity;
  for (const d of shown) if (d[o] !== null && d[o] !== undefined) { lo = Math.min(lo, d[o]); hi = Math.max(hi, d[o]); }
  return isFinite(lo) ? [lo, hi] : null;
}

function trendLabel(v) { return Number(Number(v).toPrecision(6)).toString(); }

// a trace as steps (PLC values hold between scans) in a band [top, top + height]
function drawSteps(g, shown, o, X, Y) {
  g.beginPath();
  let first = true, prevY = 0;
  for (const d of shown) {
    if (d[o] === null || d[o] === undefined) { first = true; continue; }
    const x = X(d.t), y = Y(d[o]);
    if (first) g.moveTo(x, y); else { g.lineTo(x, prevY); g.lineTo(x, y); }
    first = false; prevY = y;
  }
  g.stroke();
}

function drawTrend() {
  const cv = $("#trend"), tr = state.trend;
  if (!tr.bits) tr.bits = new Set();
  const objs = tr.objects, bits = objs.filter(isBitTrend), words = objs.filter((o) => !isBitTrend(o));
  const L = 90, R = 230, T = 16, B = 44;  // legends and ranges right of the plot
  const plotH = Math.max(words.length * (STRIP_H + STRIP_GAP) + bits.length * LANE_H, 120);
  const H = T + plotH + B;
  if (cv.height !== H) cv.height = H;
  const W = cv.width, g = cv.getContext("2d");
  g.clearRect(0, 0, W, H); g.font = "12px sans-serif"; g.lineWidth = 1;
  const data = tr.data, t0 = Math.max(0, (data.length ? data[data.length - 1].t : 0) - tr.window);
  const shown = data.filter((d) => d.t >= t0);
  const X = (t) => L + (t - t0) / tr.window * (W - L - R), right = W - R;
  const colour = (o) => COLOURS[objs.indexOf(o) % COLOURS.length];
  // time grid over the whole height
  g.strokeStyle = "#e3e7eb"; g.fillStyle = "#1d232a"; g.textAlign = "center";
  for (let k = 0; k <= 6; k++) {
    const t = t0 + tr.window * k / 6, x = X(t);
    g.beginPath(); g.moveTo(x, T); g.lineTo(x, T + plotH); g.stroke();
    g.fillText(t.toFixed(1), x, T + plotH + 16);
  }
  g.fillText("PLC time (s)", L + (W - L - R) / 2, H - 8);
  if (!objs.length) {
    g.textAlign = "left"; g.fillStyle = "#66707a";
    g.fillText("add objects above: words get a strip and an axis each, bits a 0/1 lane", L + 10, T + 30);
  }
  let y = T;
  tr.layout = [];  // where each trace was drawn: for a reader of the page (and its tests)
  for (const o of words) {  // a strip each, its own axis over its min..max in the window
    const r = trendRange(shown, o);
    let [lo, hi] = r || [0, 1];
    if (lo === hi) { lo -= 1; hi += 1; }
    const pad = (hi - lo) * 0.08, top = y, Y = (v) => top + (hi + pad - v) / (hi - lo + 2 * pad) * STRIP_H;
    g.strokeStyle = "#c9d0d7"; g.strokeRect(L, top, right - L, STRIP_H);
    g.fillStyle = "#1d232a"; g.textAlign = "right";
    for (const v of r ? (r[0] === r[1] ? [r[0]] : [r[0], (r[0] + r[1]) / 2, r[1]]) : []) {
      g.strokeStyle = "#eef1f4"; g.beginPath(); g.moveTo(L, Y(v)); g.lineTo(right, Y(v)); g.stroke();
      g.fillText(trendLabel(v), L - 6, Y(v) + 4);
    }
    g.strokeStyle = colour(o); g.lineWidth = 2; drawSteps(g, shown, o, X, Y); g.lineWidth = 1;
    g.fillStyle = colour(o); g.fillRect(right + 12, top + 8, 16, 4);
    g.fillStyle = "#1d232a"; g.textAlign = "left"; g.fillText(o, right + 34, top + 14);
    g.fillStyle = "#66707a";
    g.fillText(r ? `min ${trendLabel(r[0])}` : "no value", right + 34, top + 32);
    if (r) g.fillText(`max ${trendLabel(r[1])}`, right + 34, top + 48);
    tr.layout.push({ object: o, kind: "word", top, height: STRIP_H, min: r && r[0], max: r && r[1], colour: colour(o) });
    y += STRIP_H + STRIP_GAP;
  }
  for (const o of bits) {  // a lane each: 0 at its foot, 1 near its top
    const top = y, Y = (v) => top + LANE_H - 5 - v * (LANE_H - 10);
    g.strokeStyle = "#c9d0d7"; g.strokeRect(L, top, right - L, LANE_H);
    g.fillStyle = "#66707a"; g.textAlign = "right";
    g.fillText("1", L - 6, Y(1) + 4); g.fillText("0", L - 6, Y(0) + 4);
    g.strokeStyle = colour(o); g.lineWidth = 2; drawSteps(g, shown, o, X, Y); g.lineWidth = 1;
    g.fillStyle = colour(o); g.fillRect(right + 12, top + LANE_H / 2 - 2, 16, 4);
    g.fillStyle = "#1d232a"; g.textAlign = "left"; g.fillText(o + " (bit)", right + 34, top + LANE_H / 2 + 4);
    tr.layout.push({ object: o, kind: "bit", top, height: LANE_H, colour: colour(o) });
    y += LANE_H;
  }
  if (tr.paused) { g.fillStyle = "#e07b00"; g.textAlign = "left"; g.fillText("paused", L + 6, T + 14); }
}
