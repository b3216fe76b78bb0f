// Symbols in the web monitor (issue 24): the symbol shown beside an address, its comment
// as a tooltip, and a symbol typed where an address is (START_PB, STAR_TIME.P, STATE:2).
// The names come from /api/info ("symbols": {address: [symbol, comment]}).
"use strict";

function symbolEntry(addr) {
  const s = state.info && state.info.symbols;
  return (s && s[addr]) || null;
}
// the symbol of an address, or of the block a field belongs to (%TM0.V -> STAR_TIME.V)
function symbolOf(addr) {
  const e = symbolEntry(addr);
  if (e) return e[0];
  const m = /^(%[A-Z]+\d+)\.([A-Z]+)$/.exec(addr);
  const b = m && symbolEntry(m[1]);
  return b ? b[0] + "." + m[2] : "";
}
function commentOf(addr) {
  const e = symbolEntry(addr) || symbolEntry(addr.replace(/\.[A-Z]+$/, ""));
  return e ? e[1] : "";
}
// a label for a table, list or chip: the symbol, with the comment as its tooltip
function symbolTag(addr) {
  const name = symbolOf(addr);
  return name ? h("span", { class: "sym", title: commentOf(addr) || name }, name) : "";
}
// the symbol column of the simulation panel's I/O rows: the name shown, the comment as tooltip
function ioSymbol(addr) {
  const name = symbolOf(addr);
  return h("span", { class: "iosym", title: commentOf(addr) || name }, name);
}
// what the user typed -> its address, by the daemon's resolver (GET /api/resolve: a symbol in
// any case, with .FIELD, :N, :Xk; the one resolution path of softplc.twido.symbols); null,
// with the daemon's message shown (unknown symbol, did you mean ...), if it names nothing
async function toAddress(text) {
  try {
    const r = await fetch("/api/resolve?obj=" + encodeURIComponent(text.trim()));
    const data = await r.json();
    if (!r.ok) { say(data.error || r.statusText); return null; }
    return data.address;
  } catch (e) { say("daemon unreachable: " + e); return null; }
}
