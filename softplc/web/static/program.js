// The running program (issue 24): its version in the header, its IL listing beside the live
// ladder and in the Program tab, and an online change: upload or paste a program (and a
// configuration, or keep the running one), see its errors (line:col) or what it would
// lose, confirm, and the daemon swaps it between two scans (POST /api/program).
"use strict";

const prog = { source: "", rungs: [], shownRung: 0, pending: null };

// a POST whose refusal is shown here (errors, losses), not only as a message
async function postProgram(body) {
  const headers = { "Content-Type": "application/json" };
  const token = localStorage.getItem("softplc.token");
  if (token) headers.Authorization = "Bearer " + token;
  try {
    const r = await fetch("/api/program", { method: "POST", headers, body: JSON.stringify(body) });
    return { status: r.status, data: await r.json() };
  } catch (e) { return { status: 0, data: { error: "daemon unreachable: " + e } }; }
}

function showVersion(v) {
  const text = `v${v.version} · ${v.hash} · ${v.loaded_at.replace("T", " ")}`;
  $("#version").textContent = text;
  $("#version").title = `${v.file}\nsha256 ${v.sha256}\nloaded ${v.loaded_at}; ` +
    `${v.version} online change(s) since the daemon started`;
  $("#prog-version").textContent = `${v.file}: version ${v.version}, sha256 ${v.hash}…, loaded ${v.loaded_at}`;
}

// the listing: one line per row with its number; the lines of `rung` highlighted
function renderListing(box, rung) {
  const r = prog.rungs.find((x) => x.index === rung);
  box.innerHTML = "";
  prog.source.split("\n").forEach((line, i) => {
    const n = i + 1, hit = r && n >= r.first_line && n <= r.last_line;
    box.append(h("div", { class: "ln" + (hit ? " hit" : ""), "data-line": n },
      h("span", { class: "n" }, String(n)), line || " "));
  });
  const first = box.querySelector(".hit");
  if (first) box.scrollTop = first.offsetTop - box.offsetTop - 40;
}

async function loadListing() {
  try {
    const r = await fetch("/api/program");
    const p = await r.json();
    prog.source = p.source; prog.rungs = p.rungs;
    showVersion(p.info);
    renderListing($("#il-listing"), prog.shownRung);
    renderListing($("#prog-listing"), -1);
  } catch (e) { say("program listing: " + e); }
}

document.addEventListener("rung-shown", (e) => {
  prog.shownRung = e.detail;
  const r = state.info.rungs[e.detail];
  if (r) renderListing($("#il-listing"), r.index);
});

// ---- online change ---------------------------------------------------------------------
async function readFileInto(input, area) {
  const f = input.files[0];
  if (f) { area.value = await f.text(); area.dataset.file = f.name; }
}
$("#prog-file").addEventListener("change", (e) => readFileInto(e.target, $("#prog-text")));
$("#prog-config-file").addEventListener("change", (e) => readFileInto(e.target, $("#prog-config")));

function showOutcome(kind, title, items = [], buttons = []) {
  const box = $("#prog-result");
  box.className = "prog-result " + kind; box.innerHTML = "";
  box.append(h("b", {}, title));
  if (items.length) box.append(h("ul", {}, ...items.map((t) => (t instanceof Node ? t : h("li", {}, t)))));
  if (buttons.length) box.append(h("div", { class: "toolbar" }, ...buttons));
}

const PENDING_LOOK_MS = 2000;  // a swap still being made: look at the version again then

async function sendProgram(extra = {}) {
  const text = $("#prog-text").value;
  if (!text.trim()) { showOutcome("bad", "Paste a program or choose a file first."); return; }
  const config = $("#prog-config").value;
  const body = { program: text, file: $("#prog-text").dataset.file || "<web upload>",
                 config: config.trim() ? config : null, ...extra };
  showOutcome("busy", "Checking and compiling…");
  const { status, data } = await postProgram(body);
  if (status === 200 && data.applied) {
    showOutcome("ok", `Loaded: version ${data.info.version}, sha256 ${data.info.hash}` +
      (data.cold ? " (cold restart)" : ""), data.losses.map((l) => "lost: " + l));
    say("program loaded", true);
    await programChanged();
  } else if (status === 200) {
    showOutcome("warn", "This change loses state: it is not loaded yet.", data.losses, [
      h("button", { id: "prog-confirm", onclick: () => sendProgram({ confirm: true }) }, "Confirm and load"),
      h("button", { id: "prog-cold", onclick: () => sendProgram({ cold: true }) }, "Load with a cold restart"),
      h("button", { onclick: () => showOutcome("", "Not loaded: nothing changed.") }, "Cancel")]);
  } else if (status === 202) {  // the scan thread is still making the swap
    showOutcome("warn", data.error);
    setTimeout(programChanged, PENDING_LOOK_MS);
  } else if (data.errors && data.errors.length) {
    showOutcome("bad", `Not loaded, nothing changed: ${data.errors.length} error(s)`,
      data.errors.map((d) => h("li", { class: "err", title: "show this line in the program",
        onclick: () => selectLine($("#prog-text"), d.line) },
      `line ${d.line}:${d.column}: ${d.message}` + (d.text ? ` (at '${d.text}')` : "")
        + (d.expected ? `; expected ${d.expected}` : ""))));
  } else {
    showOutcome("bad", data.error || `refused (HTTP ${status})`);
  }
}
$("#prog-load").addEventListener("click", () => sendProgram());

// select line n (1-based) of a textarea and scroll it into view
function selectLine(area, n) {
  const lines = area.value.split("\n");
  if (n < 1 || n > lines.length) return;
  const start = lines.slice(0, n - 1).reduce((a, l) => a + l.length + 1, 0);
  area.focus(); area.setSelectionRange(start, start + lines[n - 1].length);
  const lh = area.scrollHeight / lines.length;
  area.scrollTop = Math.max(0, (n - 4) * lh);
}
$("#prog-current").addEventListener("click", () => {
  $("#prog-text").value = prog.source; $("#prog-text").dataset.file = "";
});

// after a load: rungs, symbols and version come again from the daemon
async function programChanged() {
  const r = await fetch("/api/info");
  state.info = await r.json();
  buildTables(); buildRungs(); buildTrendChips();
  await loadListing();
  if (typeof loadMap === "function" && state.tab === "map") loadMap();
}

for (const b of $$("#tabs button[data-tab=program]")) b.addEventListener("click", loadListing);
loadListing();
