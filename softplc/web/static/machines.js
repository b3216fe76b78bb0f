// softplc web monitor: the Machine tab. One view per device family, not per program: the
// first view whose fits(devices) holds draws. The daemon sends each device's status with,
// under "view", the geometry a drawing needs (each device's view()), the active
// Grafcet steps ("steps") and, on a machine with a scope, the estimator's words ("estimate").
// Loaded before app.js; uses its helpers ($, h, state) only when called.
"use strict";

const MACHINE_HISTORY_S = 30;  // machine time the FE chart and the axes' trail keep
const AXIS_COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];
const mnum = (v, digits = 3) => (typeof v === "number" && isFinite(v) ? v.toFixed(digits) : "–");
const esc = (s) => String(s).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);

function showMachine(m) {
  const mc = state.machine;
  if (m.trace_from === 0) { mc.trace = []; mc.paths = null; }
  for (const s of m.trace) mc.trace.push(s);  // (a spread of a large chunk overflows the stack)
  mc.total = m.trace_total; mc.next = m.trace_next;  // samples recorded; looked at so far
  mc.devices = m.devices; mc.steps = m.steps; mc.estimate = m.estimate;
  machineHistory(mc, m);
  let rows = "";
  for (const [name, st] of Object.entries(m.devices)) {
    const shown = Object.entries(st).filter(([k]) => k !== "type" && k !== "view")
      .concat(st.view && st.view.work ? [[`homed (program, ${st.view.work.homed_by})`, st.view.work.homed]] : [])
      .map(([k, v]) => `${k}=${typeof v === "number" ? Number(v.toPrecision(6)) : v}`).join("  ");
    rows += `<tr><td>${esc(name)}</td><td>${esc(st.type)}</td><td>${esc(shown)}</td></tr>`;
  }
  putHTML($("#devices tbody"), rows);  // (putHTML, putText: app.js) only what changed
  showSequence(mc);
  const view = MACHINE_VIEWS.find((v) => v.fits(m.devices));
  const svg = $("#table-view");
  if (view) view.draw(svg, mc);
  else {
    putAttr(svg, "viewBox", "0 0 600 615");
    putHTML(svg, `<text x="20" y="40" font-size="16" fill="#66707a">no machine view for these devices</text>`);
    putText($("#machine-hint"), "");
  }
}

// servo axes' positions and FE per update, for the trail and the FE chart (machine time)
function machineHistory(mc, m) {
  const hist = mc.history || (mc.history = []);
  if (hist.length && m.time < hist[hist.length - 1].t) hist.length = 0;  // a restart
  const axes = {};
  for (const [name, d] of Object.entries(m.devices)) if (d.type === "servo_axis" && d.view) axes[name] = d.view;
  if (!Object.keys(axes).length) return;
  hist.push({ t: m.time, axes });
  while (hist.length && hist[0].t < m.time - MACHINE_HISTORY_S) hist.shift();
}

// "step 3: title", unless the title says which step it is already
const stepText = (n, title) => (new RegExp(`^step ${n}\\b`, "i").test(title) ? title : `step ${n}: ${title}`);

// the Grafcet's active steps and the mass estimate, beside the drawing
function showSequence(mc) {
  let out = "";
  if (mc.steps) {
    const act = mc.steps.active;
    out += `<h3>Sequence</h3><p id="machine-step">${esc(act.length
      ? act.map((n) => stepText(n, mc.steps.titles[n] || "")).join("; ") : "no step active")}</p>`;
  }
  const e = mc.estimate;
  if (e) {
    const rows = [["host requests / answers", `${e.requests} / ${e.answers}`],
      ["status", e.status === 0 ? "0 (ok)" : String(e.status)]];
    if (e.answers > 0 && e.status === 0)  // the result words are the host's last answer
      rows.push(["estimated mass", mnum(e.mass_kg, 1) + " kg"], ["uncertainty", "± " + mnum(e.uncertainty_kg, 1) + " kg"],
        ["fitted acceleration", mnum(e.accel, 4) + " m/s²"], ["parameter row", String(e.row)]);
    else rows.push(["estimated mass", e.answers > 0 ? "refused (status above)" : "no estimate yet"]);
    out += `<h3>Mass estimate</h3><table id="machine-estimate" class="devices"><tbody>` +
      rows.map(([k, v]) => `<tr><td>${esc(k)}</td><td>${esc(v)}</td></tr>`).join("") + "</tbody></table>";
  }
  putHTML($("#machine-panel"), out);
}

// an axis as a drawing sees it: unit name, axis units per unit, travel [lo, hi] in units
function axisGeometry(d) {
  if (d.type === "stepper") return { unit: "cm", per: d.view.steps_per_unit, lo: 0, hi: d.view.travel, pos: d.pos / d.view.steps_per_unit };
  const v = d.view, per = v.counts_per_mm;
  return { unit: "mm", per, lo: (v.lo ?? v.x) / per, hi: (v.hi ?? v.x) / per, pos: v.x / per };
}
function niceTick(span) {  // 1, 2 or 5 times a power of ten, about 6 ticks
  const raw = span / 6, p = Math.pow(10, Math.floor(Math.log10(raw)));
  return [1, 2, 5, 10].map((k) => k * p).find((s) => s >= raw);
}

// a plane: the travel rectangle with a grid in user units; returns the mapping
function planeFrame(gx, gz, names, box) {
  const S = Math.min(box.w / (gx.hi - gx.lo), box.h / (gz.hi - gz.lo));
  const ox = box.x, oy = box.y + (gz.hi - gz.lo) * S;
  const X = (u) => ox + (u - gx.lo) * S, Z = (u) => oy - (u - gz.lo) * S;
  let out = "";
  const tick = niceTick(Math.max(gx.hi - gx.lo, gz.hi - gz.lo));
  for (let u = Math.ceil(gx.lo / tick) * tick; u <= gx.hi + 1e-9; u += tick)
    out += `<line x1="${X(u)}" y1="${Z(gz.lo)}" x2="${X(u)}" y2="${Z(gz.hi)}" stroke="#eef1f4"/><text x="${X(u)}" y="${Z(gz.lo) + 16}" font-size="11" text-anchor="middle">${+u.toFixed(6)}</text>`;
  for (let u = Math.ceil(gz.lo / tick) * tick; u <= gz.hi + 1e-9; u += tick)
    out += `<line x1="${X(gx.lo)}" y1="${Z(u)}" x2="${X(gx.hi)}" y2="${Z(u)}" stroke="#eef1f4"/><text x="${X(gx.lo) - 6}" y="${Z(u) + 4}" font-size="11" text-anchor="end">${+u.toFixed(6)}</text>`;
  const midZ = (Z(gz.lo) + Z(gz.hi)) / 2;
  out += `<rect id="table-outline" x="${X(gx.lo)}" y="${Z(gz.hi)}" width="${(gx.hi - gx.lo) * S}" height="${(gz.hi - gz.lo) * S}" fill="none" stroke="#4a5a6a" stroke-width="2"/>` +
    `<text x="${(X(gx.lo) + X(gx.hi)) / 2}" y="${Z(gz.lo) + 32}" font-size="12" text-anchor="middle">${esc(names[0])} (${gx.unit})</text>` +
    `<text x="${box.x - 46}" y="${midZ}" font-size="12" text-anchor="middle" transform="rotate(-90 ${box.x - 46} ${midZ})">${esc(names[1])} (${gz.unit})</text>`;
  return { X, Z, svg: out, bottom: Z(gz.lo) };
}
const crosshair = (cx, cz, colour, filled, id = "") =>
  `<circle ${id ? `id="${id}" ` : ""}cx="${cx}" cy="${cz}" r="6" fill="${filled ? colour : "none"}" stroke="${colour}" stroke-width="2"/>` +
  `<line x1="${cx - 12}" y1="${cz}" x2="${cx + 12}" y2="${cz}" stroke="${colour}"/><line x1="${cx}" y1="${cz - 12}" x2="${cx}" y2="${cz + 12}" stroke="${colour}"/>`;

// A trace recorder over two axes (stepper or servo) with a pen or a torch: the drawing
// table and the cutting table. What was drawn (cut) is #pen-path; moves with the pen up
// (torch off) are the dashed #travel-path. With the program's work frame (the trace's
// `work`: origin, area, homed bit), once homed the plane is in work coordinates, as the
// host (`softplc cut`) reports them, with the work area (#work-area); before, in machine
// coordinates, labelled so.
const TRACE_MIN_PX = 0.5;  // a sample nearer than this to the last one drawn adds nothing
const traceTableView = {
  fits: (devs) => Object.values(devs).some((d) => d.type === "trace" && d.view),
  draw(svg, mc) {
    const devs = mc.devices;
    const tr = Object.values(devs).find((d) => d.type === "trace").view;
    const [xn, zn] = tr.axes, gx = axisGeometry(devs[xn]), gz = axisGeometry(devs[zn]);
    const work = tr.work && tr.work.homed ? tr.work : null;
    const shift = work ? [work.origin[0] / gx.per, work.origin[1] / gz.per] : [0, 0];
    const frame = work ? "work" : "machine";
    const wx = { ...gx, unit: `${gx.unit}, ${frame}`, lo: gx.lo - shift[0], hi: gx.hi - shift[0], pos: gx.pos - shift[0] };
    const wz = { ...gz, unit: `${gz.unit}, ${frame}`, lo: gz.lo - shift[1], hi: gz.hi - shift[1], pos: gz.pos - shift[1] };
    const tool = devs[tr.pen] || {}, torch = tool.type === "torch", on = torch ? tool.lit : tool.down;
    putAttr(svg, "viewBox", "0 0 600 615");
    const f = planeFrame(wx, wz, [xn, zn], { x: 60, y: 20, w: 520, h: 530 });
    const { down, up } = tracePaths(mc, f, gx, gz, shift);
    const colour = torch ? "#e65100" : "#1f4fa0";
    const area = work ? `<rect id="work-area" x="${f.X(0)}" y="${f.Z(work.area[1])}" width="${f.X(work.area[0]) - f.X(0)}" ` +
      `height="${f.Z(0) - f.Z(work.area[1])}" fill="#fff8e1" fill-opacity="0.6" stroke="#b28704" stroke-dasharray="6 3"/>` +
      `<text x="${f.X(0) + 4}" y="${f.Z(work.area[1]) - 5}" font-size="11" fill="#8a6d00">work area ${work.area[0]} × ${work.area[1]} mm</text>` : "";
    const total = mc.total ?? mc.trace.length, got = mc.next ?? mc.trace.length, loading = got < total;
    putHTML(svg, f.svg.replace('<rect id="table-outline"', area + '<rect id="table-outline"') +
      (up ? `<path id="travel-path" d="${up}" fill="none" stroke="#9aa5b1" stroke-width="1" stroke-dasharray="4 3"/>` : "") +
      (down ? `<path id="pen-path" d="${down}" fill="none" stroke="${colour}" stroke-width="2"/>` : "") +
      crosshair(f.X(wx.pos), f.Z(wz.pos), torch ? "#e65100" : "#d62728", on, "tool") +
      (loading ? `<text id="trace-loading" x="300" y="40" font-size="14" text-anchor="middle" fill="#8a4b00">` +
        `loading the trace: ${Math.floor(100 * got / total)} % (${got} of ${total} samples)…</text>` : ""));
    const what = torch ? `torch ${on ? "lit (cutting)" : "off"}` : `pen ${on ? "down" : "up"}`;
    const where = `${xn} = ${mnum(wx.pos, 3)} ${gx.unit}, ${zn} = ${mnum(wz.pos, 3)} ${gz.unit}`;
    putText($("#machine-hint"), (work ? `${where} (work coordinates, as the host reports them; machine: ` +
      `${mnum(gx.pos, 3)}, ${mnum(gz.pos, 3)}), ` : tr.work ? `${where} (machine coordinates: not homed, ` +
      `${tr.work.homed_by} = 0, no work origin yet), ` : `${where}, `) + `${what}; ` +
      `${got} trace samples${loading ? ` of ${total} (loading)` : ""}; the ` +
      `${torch ? "orange line is what the torch cut" : "blue line is what the pen drew"}, dashed: moves with the ` +
      (torch ? "torch off." : "pen up."));
  },
};

// the trace as two SVG paths, built on from the samples added since the last draw (a
// long trace is not formatted again on every update); rebuilt when the frame changes
function tracePaths(mc, f, gx, gz, shift) {
  const key = [f.X(0), f.Z(0), f.X(1), gx.per, gz.per, ...shift].join();
  let c = mc.paths;
  if (!c || c.key !== key || c.n > mc.trace.length) c = mc.paths = { key, n: 0, down: "", up: "", last: null };
  let { down, up, last } = c;
  const tr = mc.trace;
  for (let i = c.n; i < tr.length; i++) {
    const [, sx, sz, pen] = tr[i];
    const x = f.X(sx / gx.per - shift[0]), y = f.Z(sz / gz.per - shift[1]);
    if (last && !pen === !last.pen && Math.abs(x - last.x) < TRACE_MIN_PX && Math.abs(y - last.y) < TRACE_MIN_PX) continue;
    const p = `${x.toFixed(1)},${y.toFixed(1)}`;
    if (last) {  // a run of moves with the pen up is one subpath: its dashes run on
      if (pen && last.pen) down += `L${p}`;
      else up += (last.up ? "" : `M${last.p}`) + `L${p}`;
    }
    if (pen && !(last && last.pen)) down += `M${p}`;
    last = { p, x, y, pen, up: last !== null && !(pen && last.pen) };
  }
  Object.assign(c, { n: tr.length, down, up, last });
  return c;
}

// FE against machine time, one line per servo axis, with its envelope over the servo-rate
// trace between two updates (the band): at `box` in the svg, legend right of the plot
function feChart(mc, names, box) {
  const hist = mc.history || [];
  if (!hist.length) return "";
  const t0 = Math.max(0, hist[hist.length - 1].t - MACHINE_HISTORY_S);  // from 0 at start
  let m = 1;
  for (const s of hist) for (const n of names) if (s.axes[n]) m = Math.max(m, Math.abs(s.axes[n].fe_lo), Math.abs(s.axes[n].fe_hi));
  const step = niceTick(2 * m); m = Math.ceil(m / step) * step;
  const X = (t) => box.x + (t - t0) / MACHINE_HISTORY_S * box.w, Y = (v) => box.y + (m - v) / (2 * m) * box.h;
  let out = `<g id="fe-chart"><rect x="${box.x}" y="${box.y}" width="${box.w}" height="${box.h}" fill="#fff" stroke="#c9d0d7"/>`;
  for (let v = -m; v <= m + step / 2; v += step)
    out += `<line x1="${box.x}" y1="${Y(v)}" x2="${box.x + box.w}" y2="${Y(v)}" stroke="#eef1f4"/><text x="${box.x - 5}" y="${Y(v) + 4}" font-size="10" text-anchor="end">${+v.toPrecision(4)}</text>`;
  for (let k = 0; k <= 6; k++) {
    const t = t0 + MACHINE_HISTORY_S * k / 6;
    out += `<text x="${X(t)}" y="${box.y + box.h + 14}" font-size="10" text-anchor="middle">${t.toFixed(0)}</text>`;
  }
  out += `<text x="${box.x + box.w / 2}" y="${box.y + box.h + 30}" font-size="11" text-anchor="middle">machine time (s)</text>` +
    `<text x="${box.x - 44}" y="${box.y + box.h / 2}" font-size="11" text-anchor="middle" transform="rotate(-90 ${box.x - 44} ${box.y + box.h / 2})">following error (counts)</text>`;
  names.forEach((n, i) => {
    const c = AXIS_COLOURS[i % AXIS_COLOURS.length], pts = hist.filter((s) => s.axes[n]);
    if (!pts.length) return;
    const band = pts.map((s) => `${X(s.t).toFixed(1)},${Y(s.axes[n].fe_hi).toFixed(1)}`)
      .concat(pts.slice().reverse().map((s) => `${X(s.t).toFixed(1)},${Y(s.axes[n].fe_lo).toFixed(1)}`));
    out += `<polygon points="${band.join(" ")}" fill="${c}" fill-opacity="0.18" stroke="none"/>` +
      `<polyline class="fe-line" data-axis="${esc(n)}" points="${pts.map((s) => `${X(s.t).toFixed(1)},${Y(s.axes[n].fe).toFixed(1)}`).join(" ")}" fill="none" stroke="${c}" stroke-width="1.5"/>` +
      `<rect x="${box.x + box.w + 10}" y="${box.y + 6 + i * 18}" width="14" height="4" fill="${c}"/>` +
      `<text x="${box.x + box.w + 28}" y="${box.y + 11 + i * 18}" font-size="11">${esc(n)}</text>`;
  });
  return out + `<text x="${box.x + box.w + 10}" y="${box.y + 16 + names.length * 18}" font-size="10" fill="#66707a">band: min-max</text></g>`;
}
const servoNames = (devs) => Object.keys(devs).filter((n) => devs[n].type === "servo_axis" && devs[n].view);
const axisText = (n, v) => `${n} = ${mnum(v.x / v.counts_per_mm, 3)} mm (commanded ${mnum(v.cmd / v.counts_per_mm, 3)}), ` +
  `FE ${mnum(v.fe, 1)} counts, ${mnum(v.v / v.counts_per_mm, 1)} mm/s${v.enabled ? "" : ", loop open"}`;

// Two servo axes without a trace recorder (the servo XY table): the plane with the
// carriage, its trail, and the FE chart of both axes
const servoTableView = {
  fits: (devs) => servoNames(devs).length >= 2,
  draw(svg, mc) {
    const devs = mc.devices, [xn, yn] = servoNames(devs), gx = axisGeometry(devs[xn]), gy = axisGeometry(devs[yn]);
    putAttr(svg, "viewBox", "0 0 600 615");
    const f = planeFrame(gx, gy, [xn, yn], { x: 70, y: 14, w: 500, h: 370 });
    const hist = mc.history || [];
    const trail = hist.filter((s) => s.axes[xn] && s.axes[yn])
      .map((s) => `${f.X(s.axes[xn].x / gx.per).toFixed(1)},${f.Z(s.axes[yn].x / gy.per).toFixed(1)}`);
    const vx = devs[xn].view, vy = devs[yn].view;
    putHTML(svg, f.svg +
      (trail.length > 1 ? `<polyline id="axes-trail" points="${trail.join(" ")}" fill="none" stroke="#1f4fa0" stroke-width="1.5"/>` : "") +
      `<circle cx="${f.X(vx.cmd / gx.per)}" cy="${f.Z(vy.cmd / gy.per)}" r="3" fill="#2ca02c"/>` +
      crosshair(f.X(gx.pos), f.Z(gy.pos), "#d62728", vx.enabled && vy.enabled, "carriage") +
      feChart(mc, [xn, yn], { x: 70, y: f.bottom + 56, w: 420, h: 130 }));
    putText($("#machine-hint"), `${axisText(xn, vx)}; ${axisText(yn, vy)}. Red: the carriage, green dot: ` +
      `the commanded position, blue: its last ${MACHINE_HISTORY_S} s; the FE band is the servo-rate trace's min-max between two updates.`);
  },
};

// One servo axis (the machining centre's feed axis): the travel with the carriage and
// the commanded position, the FE chart; the sequence and the estimate are in the panel
const singleAxisView = {
  fits: (devs) => servoNames(devs).length === 1,
  draw(svg, mc) {
    const devs = mc.devices, [n] = servoNames(devs), v = devs[n].view, g = axisGeometry(devs[n]);
    putAttr(svg, "viewBox", "0 0 600 360");
    const L = 70, W = 480, y = 60, X = (u) => L + (u - g.lo) / (g.hi - g.lo) * W;
    let out = `<rect id="axis-travel" x="${L}" y="${y}" width="${W}" height="26" fill="#f4f6f8" stroke="#4a5a6a" stroke-width="2"/>`;
    const tick = niceTick(g.hi - g.lo);
    for (let u = Math.ceil(g.lo / tick) * tick; u <= g.hi + 1e-9; u += tick)
      out += `<line x1="${X(u)}" y1="${y + 26}" x2="${X(u)}" y2="${y + 32}" stroke="#4a5a6a"/><text x="${X(u)}" y="${y + 46}" font-size="11" text-anchor="middle">${+u.toFixed(6)}</text>`;
    out += `<text x="${L + W / 2}" y="${y + 64}" font-size="12" text-anchor="middle">${esc(n)} (${g.unit})</text>` +
      `<rect id="carriage" x="${X(g.pos) - 7}" y="${y - 8}" width="14" height="42" fill="${v.enabled ? "#d62728" : "none"}" stroke="#d62728" stroke-width="2"/>` +
      `<path d="M${X(v.cmd / g.per) - 6},${y - 18} L${X(v.cmd / g.per) + 6},${y - 18} L${X(v.cmd / g.per)},${y - 9} Z" fill="#2ca02c"/>` +
      `<text x="${L}" y="${y - 26}" font-size="12">${esc(axisText(n, v))}</text>`;
    putHTML(svg, out + feChart(mc, [n], { x: L, y: 170, w: 420, h: 130 }));
    putText($("#machine-hint"), `Red: the carriage (filled: loop closed), green: the commanded position; ` +
      `moving mass: configured x ${mnum(1 + v.load_mass_ratio, 4)}.`);
  },
};

const MACHINE_VIEWS = [traceTableView, servoTableView, singleAxisView];
