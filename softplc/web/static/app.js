// softplc web monitor. Plain JavaScript, no libraries, nothing loaded from outside.
// Live data comes over one websocket (/api/ws); every change is a POST to /api/... that the
// daemon queues and applies at the next scan boundary.
"use strict";

const $ = (s, el = document) => el.querySelector(s);
const $$ = (s, el = document) => [...el.querySelectorAll(s)];
const h = (tag, attrs = {}, ...kids) => {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null) e.setAttribute(k, v);
  }
  for (const k of kids) e.append(k instanceof Node ? k : document.createTextNode(k));
  return e;
};

const params = new URLSearchParams(location.search);
if (params.get("token")) localStorage.setItem("softplc.token", params.get("token"));
// what the browser kept: anything malformed (an older page's, edited by hand) is dropped
function saved(key, fallback, ok) {
  try {
    const v = JSON.parse(localStorage.getItem(key) || "null");
    if (v !== null && ok(v)) return v;
  } catch (e) { /* unreadable: the default */ }
  return fallback();
}
const isTables = (t) => Array.isArray(t) && t.length > 0 && t.every((x) => x && typeof x.name === "string"
  && Array.isArray(x.rows) && x.rows.every((r) => typeof r === "string"));
const newTables = () => [{ name: "Table 1", rows: [] }];
const state = {
  info: null, status: null, forced: {}, tab: "sim", rung: 0, ws: null,
  tables: saved("softplc.tables", newTables, isTables),
  table: 0, values: {},
  formats: saved("softplc.formats", () => ({}), (f) => typeof f === "object" && !Array.isArray(f)),
  trend: { objects: JSON.parse(localStorage.getItem("softplc.trends") || "[]"), data: [],
           paused: false, window: 30, bits: new Set() },
  machine: { trace: [], devices: {} },
  held: new Set(),
};

// ---- API -------------------------------------------------------------------------------
function say(text, ok = false) {
  const m = $("#message");
  m.textContent = text; m.className = "message" + (ok ? " ok" : "");
  clearTimeout(say.t); say.t = setTimeout(() => (m.textContent = ""), ok ? 2000 : 8000);
}

async function post(path, body, retry = true) {
  const headers = { "Content-Type": "application/json" };
  const token = localStorage.getItem("softplc.token");
  if (token) headers.Authorization = "Bearer " + token;
  try {
    const r = await fetch("/api/" + path, { method: "POST", headers, body: JSON.stringify(body) });
    const data = await r.json();
    if (r.status === 401 && retry) {  // the monitor listens beyond loopback: ask for its token
      const t = prompt(data.error + "\n\nToken (printed by softplc run at start):");
      if (t) { localStorage.setItem("softplc.token", t.trim()); return post(path, body, false); }
    }
    if (!r.ok) { post.error = data.error || r.statusText; say(post.error); return null; }
    return data;
  } catch (e) { say("daemon unreachable: " + e); return null; }
}
const write = (object, value) => post("write", { object, value });
const force = (object, value) => post("force", { object, value });
const unforce = (object) => post("unforce", { object });
const setAnalog = (object, value, force = false) => post("analog", { object, value, force });

// ---- websocket ---------------------------------------------------------------------------
function subscribe() {
  const ws = state.ws;
  if (!ws || ws.readyState !== 1) return;
  const objects = new Set(state.trend.objects);
  for (const row of currentTable().rows) {
    objects.add(row);
    for (const obj of expand(row)) {  // a word shown as float: the %MF over it and the next
      const w = /^%MW(\d+)$/.exec(obj);
      if (w && state.formats[obj] === "float") objects.add("%MF" + w[1]);
    }
  }
  const shown = !document.hidden;  // a hidden page: see the visibilitychange listener
  ws.send(JSON.stringify({ subscribe: {
    objects: [...objects], io: shown,
    rungs: shown && state.tab === "ladder" ? shownRungs() : [],
    machine: shown && state.tab === "machine" } }));
  if (shown && state.tab === "machine") state.machine.trace = [];
}
// A hidden page (another tab in front, a minimised window) asks only for the status, which
// tells it the link is alive, and the objects it records (the trends go on); the I/O, the
// live rungs and the machine's state come back, and the trends are drawn, once it is shown.
document.addEventListener("visibilitychange", () => {
  subscribe();
  if (!document.hidden && state.tab === "trends") drawTrend();
});

// one view that fails on an unexpected value must not stop the others (nor the next updates)
function guarded(what, fn) {
  try { fn(); } catch (e) { console.error(what, e); }
}

function connect() {
  const token = localStorage.getItem("softplc.token");
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/api/ws"
    + (token ? "?token=" + encodeURIComponent(token) : ""));
  state.ws = ws;
  ws.onopen = () => { $("#link").classList.add("up"); linkOpened(); subscribe(); };
  ws.onclose = (ev) => {
    linkDown(ev.code === 1013 ? "too many pages open" : "the daemon closed the connection");
    if (ev.code === 1013) say(ev.reason || "too many pages open");  // the daemon's page limit
    setTimeout(connect, ev.code === 1013 ? 5000 : 1000);
  };
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "error") { say(msg.error); return; }
    if (msg.type !== "update") return;
    linkUpdate();
    guarded("status", () => showStatus(msg.status));
    if (msg.io) guarded("io", () => showIO(msg.io));
    if (msg.analog) guarded("analog", () => showAnalog(msg.analog));
    if (msg.values) {
      Object.assign(state.values, msg.values);
      guarded("table", showTable); guarded("trends", () => trendSample(msg));
    }
    if (msg.ladder) for (const [n, svg] of Object.entries(msg.ladder)) {
      const box = $(`#ladder div[data-rung="${n}"]`);
      if (box) box.innerHTML = svg;
    }
    if (msg.machine) guarded("machine", () => showMachine(msg.machine));
  };
}

// ---- header ------------------------------------------------------------------------------
// A live field is written only when its value changed: an equal write still costs the
// browser a style, layout and paint pass, ten updates a second (about 40 % of a headless
// Chromium's CPU on the Simulation tab, docs/web.md).
function put(el, key, value) {
  if (el[key] !== value) el[key] = value;
}
const putText = (el, text) => put(el, "textContent", String(text));
// A view rebuilt from markup each update (the Machine tab's drawing, its tables): markup
// equal to what the element shows already is no DOM work (an idle machine costs the page
// nothing; a rebuild is a parse, a style, a layout and a repaint of the whole view).
const shownHTML = new WeakMap();
function putAttr(el, name, value) {
  if (el.getAttribute(name) !== value) el.setAttribute(name, value);
}
function putHTML(el, html) {
  if (shownHTML.get(el) === html) return;
  shownHTML.set(el, html); el.innerHTML = html;
}

const ms = (v) => (v === undefined ? "–" : v.toFixed(3) + " ms");
function showStatus(st) {
  state.status = st; state.forced = st.forced || {};
  const s = $("#state"); putText(s, st.state); put(s, "className", "state " + st.state);
  putText($("#scan"), ms(st.scan_last_ms));
  putText($("#scanminmax"), `${st.scan_min_ms.toFixed(3)} / ${st.scan_max_ms.toFixed(3)} ms`);
  putText($("#overruns"), st.overruns + (st.late_starts === undefined ? "" :
    ` (${st.late_starts} late, ${st.skipped_starts} skipped)`));
  putText($("#scans"), st.scans);
  putText($("#plctime"), st.time.toFixed(1) + " s");
  putText($("#clients"), st.modbus_clients ?? "–");
  putText($("#forcedcount"), Object.keys(state.forced).length);
  const f = $("#fault"); put(f, "hidden", !st.fault); putText(f, st.fault ? "HALT: " + st.fault : "");
}

const ACTION_TEXT = {
  run: "Put the controller in RUN?", stop: "STOP the controller? Outputs keep their last value in STOP.",
  warm: "Warm restart: keep the data, %S1 on the first scan?",
  cold: "COLD restart: reset %M, %MW, timers, counters and outputs?",
};
for (const b of $$(".controls button")) {
  b.addEventListener("click", async () => {
    const a = b.dataset.action;
    if (!confirm(ACTION_TEXT[a])) return;
    if (await post("control", { action: a })) say(a.toUpperCase() + " sent", true);
  });
}

// ---- tabs --------------------------------------------------------------------------------
for (const b of $$("#tabs button")) {
  b.addEventListener("click", () => {
    state.tab = b.dataset.tab;
    $$("#tabs button").forEach((x) => x.classList.toggle("active", x === b));
    $$(".tab").forEach((x) => x.classList.toggle("active", x.id === "tab-" + state.tab));
    subscribe();
    if (state.tab === "trends") drawTrend();
  });
}

// ---- simulation panel ----------------------------------------------------------------------
function buildModules() {
  const box = $("#modules"); box.innerHTML = "";
  // a column of symbols beside the addresses when the program has any (issue 33)
  $("#tab-sim").classList.toggle("has-symbols", Object.keys(state.info.symbols || {}).length > 0);
  buildAnalog();
  for (const m of state.info.modules) {
    const ins = h("div", { class: "col" }, h("h4", {}, `inputs (${m.inputs})`));
    const outs = h("div", { class: "col" }, h("h4", {}, `outputs (${m.outputs})`));
    for (let c = 0; c < m.inputs; c++) ins.append(inputRow(`%I${m.slot}.${c}`));
    for (let c = 0; c < m.outputs; c++) outs.append(outputRow(`%Q${m.slot}.${c}`));
    const cols = h("div", { class: "cols" });
    if (m.inputs) cols.append(ins);
    if (m.outputs) cols.append(outs);
    box.append(h("div", { class: "module" },
      h("h3", {}, m.slot === 0 ? "base " : `slot ${m.slot} `, h("b", {}, m.name)), cols));
  }
}

const used = (addr) => (state.info.io_used.includes(addr) ? "" : " unused");

function forceButton(addr) {
  return h("button", { class: "f", title: "force / unforce", onclick: async () => {
    if (addr in state.forced) { await unforce(addr); return; }
    const v = prompt(`Force ${addr} to (0 or 1):`, "1");
    if (v === null) return;
    await force(addr, Number(v));
  } }, "F");
}

function inputRow(addr) {
  const dev = state.info.device_io[addr] || "";
  const toggle = h("button", { class: "toggle", title: "switch: toggles", onclick: () =>
    write(addr, state.io && state.io[addr] ? 0 : 1) }, "switch");
  const push = h("button", { class: "push", title: "push button: on while held" }, "push");
  const press = (e) => { e.preventDefault(); state.held.add(addr); push.classList.add("held"); write(addr, 1); };
  const release = () => {
    if (!state.held.delete(addr)) return;
    push.classList.remove("held"); write(addr, 0);
  };
  push.addEventListener("pointerdown", press);
  push.addEventListener("pointerup", release);
  push.addEventListener("pointerleave", release);
  const row = h("div", { class: "io in" + (dev ? " driven" : "") + used(addr), "data-addr": addr },
    h("span", { class: "led" }), h("span", { class: "addr", title: commentOf(addr) }, addr), ioSymbol(addr), toggle, push,
    forceButton(addr), h("span", { class: "forced-mark" }, "F"),
    h("span", { class: "dev", title: dev ? "driven by device " + dev : "" }, dev ? "⚙ " + dev : ""));
  return row;
}

function outputRow(addr) {
  const dev = state.info.device_io[addr] || "";
  return h("div", { class: "io out" + used(addr), "data-addr": addr },
    h("span", { class: "led" }), h("span", { class: "addr", title: commentOf(addr) }, addr), ioSymbol(addr), forceButton(addr),
    h("span", { class: "forced-mark" }, "F"),
    h("span", { class: "dev", title: dev ? "drives device " + dev : "" }, dev ? "⚙ " + dev : ""));
}

function showIO(io) {
  state.io = io;
  for (const row of $$("#modules .io")) {
    const a = row.dataset.addr, on = !!io[a], forced = a in state.forced;
    row.querySelector(".led").classList.toggle("on", on);
    row.classList.toggle("forced", forced);
    const t = row.querySelector(".toggle");
    if (t) {
      t.classList.toggle("on", on);
      const locked = (row.classList.contains("driven") || forced);
      put(t, "disabled", locked); put(row.querySelector(".push"), "disabled", locked);
      put(t, "title", forced ? "forced: unforce first" : locked ? "driven by a simulated device: force it to override" : "switch: toggles");
    }
  }
}

// Analog channels: a slider per input (its signal span, in the signal's unit), a value per
// output. A slider sends its value when released (or on keys), not on every pixel of a drag.
const num = (x) => String(Number(x.toFixed(Math.abs(x) >= 100 ? 1 : 3)));
const span = (ch) => `${num(ch.min)}..${num(ch.max)} ${ch.unit || "(position)"}`;
function buildAnalog() {
  const box = $("#analog"); box.innerHTML = "";
  const chans = state.info.analog || [];
  if (!chans.length) return;
  box.append(h("h3", {}, "analog I/O"));
  for (const ch of chans) {
    const a = ch.address, dev = ch.driven_by;
    const title = `${ch.signal}, range ${ch.range}: ${span(ch)} = words ${ch.word_min}..${ch.word_max}`;
    const value = h("span", { class: "aval" }, "?");
    const word = h("span", { class: "aword" }, "");
    const row = h("div", { class: "aio " + (ch.input ? "in" : "out") + (dev ? " driven" : "") + (ch.configured ? "" : " unconfigured"), "data-addr": a,
      title: ch.configured ? title : `${a}: not configured in [analog] (no signal type): its word is shown raw` },
      h("span", { class: "addr" }, a), ioSymbol(a), h("span", { class: "sig" }, ch.signal));
    if (ch.input) {
      const step = (ch.max - ch.min) / 1000;
      const slider = h("input", { type: "range", min: ch.min, max: ch.max, step, value: ch.min,
        "aria-label": a });
      slider.addEventListener("input", () => { row.dataset.moving = "1"; value.textContent = (num(Number(slider.value)) + " " + ch.unit).trim(); });
      slider.addEventListener("change", async () => {
        await setAnalog(a, Number(slider.value), a in state.forced);
        delete row.dataset.moving;
      });
      row.append(h("span", { class: "lo" }, num(ch.min)), slider, h("span", { class: "hi" }, num(ch.max) + " " + ch.unit));
      row.append(h("button", { class: "f", title: "force / unforce", onclick: async () => {
        if (a in state.forced) await unforce(a); else await setAnalog(a, Number(slider.value), true);
      } }, "F"), h("span", { class: "forced-mark" }, "F"));
    } else {  // an output: a bar over its span, where an input has its slider
      row.append(h("span", { class: "lo" }, num(ch.min)),
        h("meter", { min: ch.min, max: ch.max, value: ch.min, "aria-label": a }),
        h("span", { class: "hi" }, num(ch.max) + " " + ch.unit), h("span", { class: "fpad" }));
    }
    row.append(value, word,
      h("span", { class: "dev", title: dev ? (ch.input ? "driven by device " : "drives device ") + dev : "" }, dev ? "⚙ " + dev : ""));
    box.append(row);
  }
}

function showAnalog(values) {
  for (const row of $$("#analog .aio")) {
    const a = row.dataset.addr, v = values[a];
    if (!v) continue;
    const ch = state.info.analog.find((c) => c.address === a);
    const forced = a in state.forced;
    row.classList.toggle("forced", forced);
    putText(row.querySelector(".aword"), `(${a} = ${v.word})`);
    const slider = row.querySelector("input[type=range]");
    if (slider) {
      put(slider, "disabled", !!(state.info.read_only || !ch.configured || (row.classList.contains("driven") && !forced)));
      put(slider, "title", !ch.configured ? "not configured in [analog]: give it a signal type to drive it"
        : slider.disabled ? "driven by a simulated device: force it (F) to override" : span(ch));
      if (row.dataset.moving) continue;  // the user is dragging: leave the slider alone
      if (v.value !== null) put(slider, "value", String(v.value));
    }
    const meter = row.querySelector("meter");
    if (meter && v.value !== null) put(meter, "value", v.value);
    // an unconfigured channel: its word means nothing physical (word 0 of a PT100 = -200 °C)
    putText(row.querySelector(".aval"), v.value === null ? "no signal" : (num(v.value) + " " + ch.unit).trim());
  }
}

// ---- animation tables ------------------------------------------------------------------
const currentTable = () => state.tables[state.table] || state.tables[0];
function saveTables() { localStorage.setItem("softplc.tables", JSON.stringify(state.tables)); }
const FORMATS = ["dec", "hex", "bin", "float", "ASCII"];

function expand(obj) {
  // client-side mirror of the server's range expansion, for display rows only; the
  // server checks every address (an unknown one comes back as an error message)
  const m = /^%(MW|MD|MF|KW|KD|KF|SW|M|S|X)(\d+):(\d+)$/i.exec(obj);
  if (m) {
    const kind = m[1].toUpperCase(), step = /^(MD|MF|KD|KF)$/.test(kind) ? 2 : 1;
    return Array.from({ length: +m[3] }, (_, k) => `%${kind}${+m[2] + k * step}`);
  }
  const io = /^%([IQ])(\d+)\.(\d+):(\d+)$/i.exec(obj);
  if (io) return Array.from({ length: +io[4] }, (_, k) => `%${io[1].toUpperCase()}${io[2]}.${+io[3] + k}`);
  return [obj.toUpperCase()];
}

function fmt(obj, v, f) {
  if (v === null || v === undefined) return "?";
  if (typeof v === "boolean") return v ? "1" : "0";  // bits are 0/1, whatever sends them
  if (typeof v === "object") return Object.entries(v).map(([k, x]) => `${k}=${x}`).join(" ");
  if (typeof v !== "number" || !Number.isFinite(v)) return String(v);
  const wide = /^%(MD|KD|MF|KF)/.test(obj), bits = wide ? 32 : 16;
  if (/^%(MF|KF)/.test(obj) || !Number.isInteger(v)) {
    if (f === "hex" || f === "bin") {
      const b = new DataView(new ArrayBuffer(4)); b.setFloat32(0, v);
      const raw = b.getUint32(0);
      return f === "hex" ? "16#" + raw.toString(16).toUpperCase().padStart(8, "0") : "2#" + raw.toString(2).padStart(32, "0");
    }
    return Number(v.toPrecision(7)).toString();
  }
  const raw = (BigInt(v) & ((1n << BigInt(bits)) - 1n));
  switch (f) {
    case "hex": return "16#" + raw.toString(16).toUpperCase().padStart(bits / 4, "0");
    case "bin": return "2#" + raw.toString(2).padStart(bits, "0").replace(/(....)(?=.)/g, "$1_");
    case "float": {
      if (!wide) {  // %MWi as float = %MFi (words i and i+1)
        if (!obj.startsWith("%MW")) return "–";
        const f = state.values["%MF" + obj.slice(3)];
        return typeof f === "number" ? Number(f.toPrecision(7)).toString() + " (%MF)" : "…";
      }
      const b = new DataView(new ArrayBuffer(4)); b.setUint32(0, Number(raw));
      return Number(b.getFloat32(0).toPrecision(7)).toString();
    }
    case "ASCII": {
      let s = "";
      for (let i = bits - 8; i >= 0; i -= 8) {
        const c = Number((raw >> BigInt(i)) & 255n);
        s += c >= 32 && c < 127 ? String.fromCharCode(c) : ".";
      }
      return "'" + s + "'";
    }
    default: return String(v);
  }
}

function parseEntry(text, obj) {
  text = text.trim();
  if (/^16#/i.test(text)) return parseInt(text.slice(3), 16);
  if (/^2#/i.test(text)) return parseInt(text.slice(2).replace(/_/g, ""), 2);
  if (/^'.*'$/.test(text) && !/^%(MF|KF)/.test(obj)) {
    let v = 0; for (const c of text.slice(1, -1)) v = v * 256 + c.charCodeAt(0); return v;
  }
  return Number(text);
}

function buildTables() {
  const sel = $("#table-select"); sel.innerHTML = "";
  state.tables.forEach((t, i) => sel.append(h("option", { value: i }, t.name)));
  sel.value = state.table;
  const body = $("#anim tbody"); body.innerHTML = "";
  for (const entry of currentTable().rows) {
    const objs = expand(entry);
    if (objs.length > 1) body.append(h("tr", { class: "group" }, h("td", { colspan: 5 }, entry),
      h("td", {}, removeButton(entry))));
    for (const obj of objs) body.append(tableRow(obj, objs.length > 1 ? null : entry));
  }
  showTable();
}

function removeButton(entry) {
  return h("button", { title: "remove from the table", onclick: () => {
    const rows = currentTable().rows; rows.splice(rows.indexOf(entry), 1);
    saveTables(); buildTables(); subscribe();
  } }, "✕");
}

function tableRow(obj, entry) {
  const sel = h("select", { onchange: () => { state.formats[obj] = sel.value;
    localStorage.setItem("softplc.formats", JSON.stringify(state.formats)); showTable(); subscribe(); } },
    ...FORMATS.map((f) => h("option", { value: f }, f)));
  sel.value = state.formats[obj] || "dec";
  const input = h("input", { class: "w", placeholder: "value" });
  const note = h("div", { class: "write-note" });  // a refused write says why, in its row
  const doWrite = async () => {
    if (input.value.trim() === "") return;
    post.error = "";
    const ok = await write(obj, parseEntry(input.value, obj));
    input.classList.toggle("refused", !ok);
    note.textContent = ok ? "" : post.error;
    if (ok) { say(`${obj} := ${input.value} queued`, true); input.value = ""; }
  };
  input.addEventListener("keydown", (e) => { if (e.key === "Enter") doWrite(); });
  const bit = /^%(I|Q|M|S|X)\d/.test(obj) && !/^%(MW|MD|MF|SW)/.test(obj);
  const forceable = bit || /^%(MW|MD|MF)\d+$/.test(obj);
  const block = /^%(TM|C|DR|R|SBR|SC)\d+$/.test(obj);  // its fields are the writable objects
  return h("tr", { "data-obj": obj },
    h("td", { class: "obj", title: commentOf(obj) }, obj, " ", symbolTag(obj), " ", h("span", { class: "forced-mark" }, "F")),
    h("td", { class: "val" }, "…"), h("td", {}, block || bit ? "" : sel),
    h("td", {}, block ? h("span", { class: "hint" }, `write ${obj}.P …`) : input, " ",
      block ? "" : h("button", { class: "write", onclick: doWrite }, "Write"), block ? "" : note),
    h("td", {}, forceable ? h("button", { class: "force", onclick: async () => {
      const v = input.value.trim() === "" ? (bit ? 1 : state.values[obj]) : parseEntry(input.value, obj);
      await force(obj, v);
    } }, "Force") : "", " ", forceable ? h("button", { class: "unforce", onclick: () => unforce(obj) }, "Unforce") : ""),
    h("td", {}, entry ? removeButton(entry) : ""));
}

function showTable() {
  for (const tr of $$("#anim tbody tr[data-obj]")) {
    const obj = tr.dataset.obj, v = state.values[obj];
    let text;
    try { text = fmt(obj, v, state.formats[obj] || "dec"); } catch (e) { text = String(v); }
    putText(tr.querySelector(".val"), text);
    tr.classList.toggle("forced", obj in state.forced);
  }
}

async function addToTable() {
  const text = $("#table-add").value;
  const addrs = [];
  for (const part of text.split(/[ ,;]+/).filter(Boolean)) {
    const addr = await toAddress(part);
    if (addr === null) return;  // the message says why; the text stays to be corrected
    addrs.push(addr);
  }
  currentTable().rows.push(...addrs);
  $("#table-add").value = ""; saveTables(); buildTables(); subscribe();
}
$("#table-add-btn").addEventListener("click", addToTable);
$("#table-add").addEventListener("keydown", (e) => { if (e.key === "Enter") addToTable(); });
$("#table-select").addEventListener("change", (e) => { state.table = +e.target.value; buildTables(); subscribe(); });
$("#table-new").addEventListener("click", () => {
  state.tables.push({ name: "Table " + (state.tables.length + 1), rows: [] });
  state.table = state.tables.length - 1; saveTables(); buildTables(); subscribe();
});
$("#table-rename").addEventListener("click", () => {
  const n = prompt("Table name:", currentTable().name); if (n) { currentTable().name = n; saveTables(); buildTables(); }
});
$("#table-delete").addEventListener("click", () => {
  if (!confirm(`Delete ${currentTable().name}?`)) return;
  state.tables.splice(state.table, 1);
  if (!state.tables.length) state.tables.push({ name: "Table 1", rows: [] });
  state.table = 0; saveTables(); buildTables(); subscribe();
});
$("#table-reset").addEventListener("click", () => {
  if (!confirm("Reset the animation tables? Every table and display format kept in this browser is removed.")) return;
  localStorage.removeItem("softplc.tables"); localStorage.removeItem("softplc.formats");
  state.tables = newTables(); state.formats = {}; state.table = 0;
  buildTables(); subscribe(); say("animation tables reset", true);
});
function download(name, text, type) {
  const a = h("a", { href: URL.createObjectURL(new Blob([text], { type })), download: name });
  document.body.append(a); a.click(); a.remove();
}
$("#table-export").addEventListener("click", () =>
  download("softplc-tables.json", JSON.stringify(state.tables, null, 2), "application/json"));
$("#table-export-csv").addEventListener("click", () => {
  const lines = ["object,value,format"];
  for (const tr of $$("#anim tbody tr[data-obj]"))
    lines.push(`${tr.dataset.obj},"${tr.querySelector(".val").textContent}",${state.formats[tr.dataset.obj] || "dec"}`);
  download(currentTable().name + ".csv", lines.join("\n") + "\n", "text/csv");
});
$("#table-import").addEventListener("change", async (e) => {
  try {
    const t = JSON.parse(await e.target.files[0].text());
    if (!isTables(t)) throw new Error("not a list of {name, rows: [addresses]}");
    state.tables.push(...t); saveTables(); buildTables(); subscribe(); say(`${t.length} table(s) imported`, true);
  } catch (err) { say("import: " + err.message); }
});

// ---- ladder ------------------------------------------------------------------------------
function buildRungs() {
  const list = $("#rung-list"); list.innerHTML = "";
  for (const r of state.info.rungs) {
    list.append(h("li", { "data-rung": r.index, title: r.il, onclick: () => showRung(r.index) },
      h("span", { class: "n" }, String(r.index)), r.title || r.il.split("\n")[0]));
  }
  showRung(0);
}
// rungs whose title or IL mentions the text (e.g. where %Q0.1 is used), or that use an
// object whose symbol has it ("JAM" finds the rungs using %M10 when JAM = %M10)
function rungMatches(r, q) {
  if (r.title.toUpperCase().includes(q) || r.il.toUpperCase().includes(q)) return true;
  return (r.uses || []).some((a) => a.toUpperCase() === q || symbolOf(a).toUpperCase().includes(q));
}
$("#rung-filter").addEventListener("input", (e) => {
  const q = e.target.value.trim().toUpperCase();
  for (const li of $$("#rung-list li"))
    li.hidden = q !== "" && !rungMatches(state.info.rungs[+li.dataset.rung], q);
});
const RUNGS_SHOWN = 4;  // the selected rung and the next ones, all live
function shownRungs() {
  const n = state.info.rungs.length;
  return Array.from({ length: Math.min(RUNGS_SHOWN, n - state.rung) }, (_, k) => state.rung + k);
}
function showRung(n) {
  const rungs = state.info.rungs;
  if (!rungs.length) return;
  state.rung = Math.max(0, Math.min(rungs.length - 1, n));
  $$("#rung-list li").forEach((li) => li.classList.toggle("active", +li.dataset.rung === state.rung));
  const r = rungs[state.rung];
  $("#rung-title").textContent = `rung ${r.index}` + (r.title ? ": " + r.title : "");
  document.dispatchEvent(new CustomEvent("rung-shown", { detail: state.rung }));  // program.js
  const box = $("#ladder"); box.innerHTML = "";
  for (const k of shownRungs()) box.append(h("div", { class: "rung", "data-rung": k }, "…"));
  subscribe();
}
$("#ladder-zoom").addEventListener("change", (e) => ($("#ladder").style.zoom = e.target.value));
$("#rung-prev").addEventListener("click", () => showRung(state.rung - 1));
$("#rung-next").addEventListener("click", () => showRung(state.rung + 1));

// ---- trends ------------------------------------------------------------------------------
const COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"];
function saveTrends() { localStorage.setItem("softplc.trends", JSON.stringify(state.trend.objects)); }
// trendSample(msg) and drawTrend(): trends.js
function buildTrendChips() {
  const box = $("#trend-objects"); box.innerHTML = "";
  state.trend.objects.forEach((o, i) => box.append(h("span", { class: "chip" },
    h("i", { style: `background:${COLOURS[i % COLOURS.length]}` }), o, symbolTag(o),
    h("button", { onclick: () => { state.trend.objects.splice(i, 1); saveTrends(); buildTrendChips(); subscribe(); } }, "✕"))));
}
async function addTrend() {
  const addrs = [];
  for (const o of $("#trend-add").value.split(/[ ,;]+/).filter(Boolean)) {
    const addr = await toAddress(o);
    if (addr === null) return;  // the message says why
    addrs.push(addr);
  }
  state.trend.objects.push(...addrs);
  $("#trend-add").value = ""; saveTrends(); buildTrendChips(); subscribe();
}
$("#trend-add-btn").addEventListener("click", addTrend);
$("#trend-add").addEventListener("keydown", (e) => { if (e.key === "Enter") addTrend(); });
$("#trend-window").addEventListener("change", (e) => { state.trend.window = +e.target.value; drawTrend(); });
$("#trend-pause").addEventListener("click", (e) => {
  state.trend.paused = !state.trend.paused; e.target.textContent = state.trend.paused ? "Resume" : "Pause"; drawTrend();
});
$("#trend-clear").addEventListener("click", () => { state.trend.data = []; drawTrend(); });
$("#trend-csv").addEventListener("click", () => {
  const objs = state.trend.objects, lines = ["t_s," + objs.join(",")];
  for (const d of state.trend.data) lines.push([d.t, ...objs.map((o) => d[o] ?? "")].join(","));
  download("softplc-trend.csv", lines.join("\n") + "\n", "text/csv");
});

// ---- machine view: machines.js ------------------------------------------------------

// ---- start -------------------------------------------------------------------------------
async function start() {
  const r = await fetch("/api/info");
  state.info = await r.json();
  $("#program").title = state.info.program;
  $("#program").textContent = `${state.info.program.split("/").pop()}  ·  ${state.info.profile}  ·  period ${state.info.period_ms} ms` +
    (state.info.read_only ? "  ·  read-only" : "");
  if (state.info.read_only) {  // a read-only monitor: no control that would be refused
    document.body.classList.add("read-only");
    $$(".controls button").forEach((b) => (b.disabled = true));
  }
  document.title = "softplc · " + state.info.program;
  buildModules(); buildTables(); buildRungs(); buildTrendChips(); drawTrend();
  connect();
}
start();
