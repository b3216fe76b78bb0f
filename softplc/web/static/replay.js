// The replay page: a counterexample of `softplc verify --cex` on the ladder, scan by scan.
// Paused: the position moves only with the slider, the buttons or the arrow keys; each
// move asks the server for that position (GET only: the page changes nothing).
"use strict";

const $ = (id) => document.getElementById(id);
let info = null;
let wanted = 0;   // the position last asked for: an older answer is dropped
let watch = [];
let timer = null;  // playing: the interval stepping forward
const PLAY_MS = 700;  // one scan shown this long while playing (to read the values)

function cell(row, text, cls) {
  const td = document.createElement(row.parentElement?.tagName === "THEAD" ? "th" : "td");
  td.textContent = text;
  if (cls) td.className = cls;
  row.appendChild(td);
  return td;
}

function fill(tbody, rows) {
  tbody.replaceChildren();
  for (const values of rows) {
    const tr = tbody.insertRow();
    for (const [text, cls] of values) cell(tr, text, cls);
  }
}

function buildHistory() {
  const ins = [...new Set(info.history.flatMap((r) => Object.keys(r.inputs)))].sort();
  const head = $("history").tHead.insertRow();
  for (const h of ["scan", ...ins]) cell(head, h);
  for (const w of watch) cell(head, w, "req");
  cell(head, "status");
  const body = $("history").tBodies[0];
  for (const r of info.history) {
    const tr = body.insertRow();
    tr.dataset.scan = r.scan;
    tr.className = r.status;
    cell(tr, r.scan);
    for (const k of ins) cell(tr, k in r.inputs ? r.inputs[k] : "");
    for (const w of watch) cell(tr, r.values[w]);
    cell(tr, r.status + (r.agree ? "" : " (model differs)"));
    tr.addEventListener("click", () => go(r.scan));
  }
}

function show(f) {
  $("slider").value = f.scan;
  $("position").textContent = `scan ${f.scan} / ${f.total}, t = ${f.time.toFixed(3)} s`;
  const st = $("status");
  st.textContent = f.status;
  st.className = "status " + f.status.split(" ")[0];
  document.body.dataset.scan = f.scan;
  fill($("values").tBodies[0], f.values.map((v) => [
    [v.object], [v.engine, f.status === "VIOLATED" ? "bad" : ""],
    [v.model === null ? "–" : v.model, v.agree ? "" : "bad"]]));
  const ins = Object.entries(f.inputs);
  fill($("inputs").tBodies[0], ins.length ? ins.map(([k, v]) => [[k], [v]])
    : [[["(cold start: no scan yet)"]]]);
  for (const tr of $("history").tBodies[0].rows) {
    tr.classList.toggle("current", Number(tr.dataset.scan) === f.scan);
  }
  const rungs = $("rungs");
  rungs.replaceChildren();
  f.rungs.forEach((svg, i) => {
    const div = document.createElement("div");
    div.className = "rung";
    div.dataset.rung = i;
    // the server's own rendering (softplc.ladder escapes every label)
    div.insertAdjacentHTML("beforeend", svg);
    rungs.appendChild(div);
    for (const label of div.querySelectorAll("svg text.req")) mark(label);
  });
}

// a yellow box behind a label of the requirement's (SVG text has no background)
function mark(label) {
  const b = label.getBBox();
  const pad = 2;
  const box = document.createElementNS("http://www.w3.org/2000/svg", "rect");
  for (const [k, v] of Object.entries({x: b.x - pad, y: b.y - pad, width: b.width + 2 * pad,
                                       height: b.height + 2 * pad, rx: 3})) {
    box.setAttribute(k, v);
  }
  box.setAttribute("class", "req-box");
  label.before(box);
}

async function go(n) {
  n = Math.max(0, Math.min(info.total, n));
  wanted = n;
  const r = await fetch(`/api/replay/scan/${n}`);
  const f = await r.json();
  if (!r.ok) { $("status").textContent = f.error; return; }
  if (f.scan === wanted) show(f);
}

function pause() {
  clearInterval(timer);
  timer = null;
  $("play").textContent = "play";
}

function play() {
  if (timer !== null) { pause(); return; }
  if (wanted >= info.total) go(0);
  $("play").textContent = "pause";
  timer = setInterval(() => {
    if (wanted >= info.total) { pause(); return; }
    go(wanted + 1);
  }, PLAY_MS);
}

async function start() {
  info = await (await fetch("/api/replay")).json();
  watch = info.watch;
  $("program").textContent = info.program;
  $("req-name").textContent = info.requirement;
  $("req-check").textContent = info.check;
  $("req-verdict").textContent = info.violated_at
    ? `VIOLATED at scan ${info.violated_at} in the scan engine (the verifier reported scan ` +
      `${info.reported}); ${info.total} scan(s) from a cold start`
    : `holds in every scan of the trace in the scan engine (the verifier reported scan ` +
      `${info.reported}): engine and model disagree`;
  $("slider").max = info.total;
  buildHistory();
  // a move by hand pauses the playing
  const by_hand = (f) => () => { pause(); f(); };
  $("slider").addEventListener("input", (e) => { pause(); go(Number(e.target.value)); });
  $("first").addEventListener("click", by_hand(() => go(0)));
  $("back").addEventListener("click", by_hand(() => go(wanted - 1)));
  $("fwd").addEventListener("click", by_hand(() => go(wanted + 1)));
  $("play").addEventListener("click", play);
  $("to-violation").addEventListener("click",
                                     by_hand(() => go(info.violated_at ?? info.total)));
  document.addEventListener("keydown", (e) => {
    if (e.target.tagName === "INPUT" && e.target.type !== "range") return;
    if (e.key === " " && e.target.tagName !== "BUTTON") { e.preventDefault(); play(); return; }
    const keys = {ArrowLeft: wanted - 1, ArrowRight: wanted + 1, Home: 0,
                  v: info.violated_at ?? info.total};
    if (e.key in keys && e.target.id !== "slider") {
      e.preventDefault();
      pause();
      go(keys[e.key]);
    }
  });
  go(0);
}

start();
