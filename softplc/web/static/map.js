// The Modbus map of the running program (issue 24): every %M/%MW/%MD/%MF object with its
// Modbus table, address, function codes, access, symbol and comment (GET /api/map), a CSV
// download for an HMI/SCADA tag import, and what the program uses that is not on the map.
"use strict";

const MAP_COLUMNS = [
  ["address", (t) => t.address], ["symbol", (t) => t.symbol], ["type", (t) => t.type],
  ["table", (t) => t.table],
  ["Modbus address", (t) => (t.count > 1 ? `${t.start}..${t.start + t.count - 1}` : String(t.start))],
  ["reference", (t) => String(t.reference)], ["FC read", (t) => t.read_fc.join(", ")],
  ["FC write", (t) => t.write_fc.join(", ") || "–"], ["access", (t) => t.access],
  ["program", (t) => t.program], ["comment", (t) => t.comment], ["note", (t) => t.note],
];

async function loadMap() {
  let m;
  try {
    const r = await fetch("/api/map");
    m = await r.json();
    if (!r.ok) throw new Error(m.error || r.statusText);
  } catch (e) { say("Modbus map: " + e.message); return; }
  const head = $("#map-tags thead"), body = $("#map-tags tbody");
  head.innerHTML = ""; body.innerHTML = "";
  head.append(h("tr", {}, ...MAP_COLUMNS.map(([name]) => h("th", {}, name))));
  for (const t of m.tags)
    body.append(h("tr", { "data-address": t.address, title: t.comment || "" },
      ...MAP_COLUMNS.map(([name, get]) => h("td", { class: name.replace(/ /g, "-").toLowerCase() }, get(t)))));
  if (!m.tags.length) body.append(h("tr", {}, h("td", { colspan: MAP_COLUMNS.length },
    "The program uses no %M, %MW, %MD or %MF object.")));
  $("#map-count").textContent = `${m.tags.length} objects on the map, program version ${m.info.version} (${m.info.hash})`;
  $("#map-note").textContent = m.note;
  const hidden = $("#map-hidden tbody"); hidden.innerHTML = "";
  for (const x of m.hidden)
    hidden.append(h("tr", { "data-address": x.address, title: x.comment || "" },
      h("td", { class: "address" }, x.address), h("td", {}, x.symbol), h("td", {}, x.program),
      h("td", {}, String(x.line)), h("td", {}, x.why)));
}

for (const b of $$("#tabs button[data-tab=map]")) b.addEventListener("click", loadMap);
