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
// what the user typed -> an address: a symbol (any case) with an optional .FIELD or :N
function toAddress(text) {
  const t = text.trim().toUpperCase();
  if (t.startsWith("%") || !state.info || !state.info.symbols) return t;
  const m = /^([A-Z_][A-Z0-9_]*)((?:\.[A-Z]+)?(?::\d+)?)$/.exec(t);
  if (!m) return t;
  for (const [addr, [name]] of Object.entries(state.info.symbols))
    if (name.toUpperCase() === m[1]) return addr + m[2];
  return t;  // unknown: the server says so
}
