"""A counterexample of `softplc verify --cex` played back in the scan engine, scan by scan,
for the replay page (`softplc.web.replay`) and `softplc replay`.

Position n is the controller after n scans of the trace from a cold start (0: the cold
start itself, before any scan). Every position reached is kept as an `Engine.snapshot()`,
so going back is a `restore`, never a re-run; going forward past the furthest one runs
the next scans with the trace's inputs (`verify.replay.set_inputs`, as the verifier's own
replay does). Nothing else writes to the controller: no Modbus server, no simulated
devices, no host.
"""

from __future__ import annotations

import html
import re
from collections.abc import Callable
from typing import Any

from softplc import ladder
from softplc.errors import SoftPLCError
from softplc.verify.replay import first_failure, set_inputs, shown

#: What the page calls each position's relation to the requirement.
COLD, HOLDS, VIOLATED, AFTER = "cold start", "holds", "VIOLATED", "after the violation"


class TracePlayer:
    """One counterexample (`item`: an entry of cex.json's "counterexamples") on the PLC
    `make_plc()` builds cold (called twice: the player's, and one for the requirement's
    own check, `first_failure`)."""

    def __init__(self, make_plc: Callable[[], Any], item: dict[str, Any]):
        self.item = item
        self.requirement = str(item.get("requirement") or item["check"])
        self.check = item["check"]
        self.inputs: list[dict[str, Any]] = [row["inputs"] for row in item["scans"]]
        self.model: list[dict[str, Any]] = [row.get("values") or {} for row in item["scans"]]
        # the requirement's objects: those the verifier listed, in its order
        self.watch: list[str] = list(self.model[0]) if self.model else []
        self.plc = make_plc()
        try:
            for k in self.watch:  # addresses of this program
                self._guard(lambda k=k: self.plc[k])
            with make_plc() as judge:  # the requirement checked on the engine's values
                self.violated_at = self._guard(lambda: first_failure(judge, self.check,
                                                                     self.inputs))
        except SoftPLCError:
            self.plc.close()
            raise
        self._snaps = [self.plc.engine.snapshot()]
        self.position = 0

    def close(self) -> None:
        self.plc.close()

    @property
    def total(self) -> int:
        return len(self.inputs)

    def _guard(self, run: Callable[[], Any], where: str = "") -> Any:
        try:
            return run()
        except (SoftPLCError, ValueError, OverflowError) as e:  # a bad address or value
            raise SoftPLCError(f"counterexample {self.requirement!r}{where}: {e}") from None

    def goto(self, n: int) -> int:
        """Move to position `n` (clamped to 0..total); the position reached."""
        n = max(0, min(int(n), self.total))
        if n < len(self._snaps):
            self.plc.engine.restore(self._snaps[n])
        else:
            self.plc.engine.restore(self._snaps[-1])
            while len(self._snaps) <= n:
                scan = len(self._snaps) - 1
                self._guard(lambda scan=scan: set_inputs(self.plc, self.inputs[scan]),
                            f", scan {scan + 1}")
                self.plc.scan()
                self._snaps.append(self.plc.engine.snapshot())
        self.position = n
        return n

    def status(self, n: int) -> str:
        if n == 0:
            return COLD
        if self.violated_at is None or n < self.violated_at:
            return HOLDS
        return VIOLATED if n == self.violated_at else AFTER

    def frame(self) -> dict[str, Any]:
        """What the page shows of the current position: the scan's inputs, the
        requirement's objects as the engine has them (and as the verifier's model had them),
        the requirement's status."""
        n = self.position
        engine = {k: _plain(self.plc[k]) for k in self.watch}
        model = self.model[n - 1] if n else {}
        return ({"scan": n, "total": self.total, "time": self.plc.time,
                      "inputs": dict(sorted(self.inputs[n - 1].items())) if n else {},
                      "values": [{"object": k, "engine": v, "model": model.get(k),
                                  "agree": n == 0 or model.get(k) == v}
                                 for k, v in engine.items()],
                      "status": self.status(n), "violated_at": self.violated_at})

    def rung_svgs(self) -> list[str]:
        """Every rung at the current position, the requirement's objects highlighted."""
        live = ladder.Live(self.plc.mem.read, None)  # as the debugger's `rung`
        return [highlight(ladder.render_rung_svg(rung, live), self.watch)
                for rung in self.plc.ast.rungs]

    def history(self) -> list[dict[str, Any]]:
        """Every scan's frame without the rungs (the page's table); the position stays."""
        here, rows = self.position, []
        for n in range(1, self.total + 1):
            self.goto(n)
            f = self.frame()
            rows.append({"scan": n, "time": f["time"], "inputs": f["inputs"],
                         "values": {v["object"]: v["engine"] for v in f["values"]},
                         "agree": all(v["agree"] for v in f["values"]),
                         "status": f["status"]})
        self.goto(here)
        return rows

    def info(self) -> dict[str, Any]:
        return {"requirement": self.requirement, "check": self.check, "total": self.total,
                "reported": self.total, "violated_at": self.violated_at,
                "watch": self.watch, "history": self.history(),
                "rungs": [{"index": r.index, "title": r.title or ""}
                          for r in self.plc.ast.rungs]}


def highlight(svg: str, names: list[str]) -> str:
    """`svg` (a rung from the ladder renderer) with the labels naming one of `names` in
    class "req" (the page draws them highlighted); a block's field (`%TM0.Q`) marks the
    block's box title (`%TM0`) too."""
    if not names:
        return svg
    blocks = [n.rpartition(".")[0] for n in names if n.rpartition(".")[2].isalpha()]
    wanted = "|".join(re.escape(html.escape(n, quote=False)) for n in names + blocks)
    return re.sub(rf'<text ([^>]*)>({wanted})</text>', r'<text class="req" \1>\2</text>', svg)


def _plain(v: Any) -> Any:
    """A bit as 0/1, a NaN or infinity as text: the way the verifier writes them."""
    return int(v) if isinstance(v, bool) else shown(v)
