// softplc web monitor: the connection to the daemon, shown where the user looks. When the
// websocket closes (the daemon stopped) or no update comes for STALE_MS, the header's state
// says DISCONNECTED and the figures grey out: the last values are not live any more. app.js
// reconnects every second; the first update afterwards puts the live state back, and a
// daemon restarted with another program reloads the page.
// Loaded before app.js; uses its helpers ($, state) only when called.
"use strict";

const STALE_MS = 4000;  // no update for this long on an open socket: not live either
// staleMs: STALE_MS, unless changed (the browser tests shorten it rather than wait 4 s)
const link = { up: false, last: 0, lost: false, staleMs: STALE_MS };

function linkDown(why) {
  link.up = false;
  document.body.classList.add("disconnected");
  const s = $("#state");
  s.textContent = "DISCONNECTED"; s.className = "state disconnected";
  s.title = why + " (reconnecting every second; the values shown are the last received)";
  $("#link").classList.remove("up");
  link.lost = true;
}

// the socket opened again: check it is the same program before trusting the page
async function linkOpened() {
  link.up = true; link.last = Date.now();
  if (!link.lost || !state.info) return;
  try {
    const info = await (await fetch("/api/info")).json();
    if (info.program !== state.info.program || info.rungs.length !== state.info.rungs.length) location.reload();
  } catch (e) { /* the next close shows it */ }
}

// every update: live again (after a hang the socket is the same: it is up again, and a
// second hang is told as the first was)
function linkUpdate() {
  link.last = Date.now();
  if (!link.up) { link.up = true; $("#link").classList.add("up"); }
  if (document.body.classList.contains("disconnected")) {
    document.body.classList.remove("disconnected"); $("#state").title = "";
  }
}

setInterval(() => {
  if (link.up && Date.now() - link.last > link.staleMs) linkDown(`no update for ${link.staleMs / 1000} s`);
}, 500);
