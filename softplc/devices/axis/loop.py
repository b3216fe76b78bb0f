"""The servo loop's cycles, generated per configuration and drive state (issue 12's speed).

`compile_cycles(render(values, flags), ...)` gives `cycles(dev, n) -> cycles left`: up to
n servo cycles of the device `dev` (a ServoAxis), its state read into locals once and
written back once; an event (fatal following error, end of an open-loop output, the homing
index pulse) stops the cycles and goes to `dev.runner.on_event`. A cycle first integrates
the plant over the period that ends at its tick (the output computed at the previous tick
held), then reads the encoder and computes the new output: state, count, commanded
position and following error are then all the tick's.

The source below is the one description of a cycle. Lines tagged `?flag` are kept only
when the flag holds, `!flag` only when it does not (`?a&!b`, `?a|b` combine flags);
`$name` is a constant of the configuration, written as a literal (`repr` of a float
round-trips exactly). Only code that cannot change a result is dropped: a branch whose
test is false for the configuration (no DAC quantisation, no current limit, no load
table, no trace) or the drive state of the scan (loop closed, open loop, killed, homing
search, faulted), or `- 0.0` and `1.0 *` (exact identities), and where u can never be
-0.0 (the law's offset Ixx29 is not -0.0: every value u takes is then +0.0 or non-zero)
`+ 0.0` on u, a law term whose gain is 0 (0 x a finite term is +-0.0, which the sum's
last `+ Ixx29` cannot tell from nothing), the friction's branches with no friction.
What remains is the same operations in the same order, so the results are bit for bit
those of one generic loop (checked against the previous generic implementation: identical
traces and words; tests/unit/test_servo_axis.py compares the generated scan with the generic
update). A function is compiled once per distinct source and cached.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from string import Template
from typing import Any

from softplc.devices.axis import status
from softplc.runtime.codecache import compile_code

_HEAD = """\
    x = dev.x_
    v = dev.v_
    k = dev.k
    cp = dev._cp_
    cpp = dev._cpp_
    cvp = dev._cvp_
    app = dev._app_
    ie = dev._ie_
    clamped = dev._clamped_
    u = dev.u_
    w = dev.w_
    fe = dev.fe_
    fe_max = dev.fe_max_
?closed    traj = dev._traj_
?closed    k0 = dev._k0
?closed    tail_v = dev._tail_v_
?closed    ntraj = len(traj)
?trace    rec = dev._rec
?gather    gat = dev.gather.append
?trace|gather    origin = dev.origin_
?open_loop    ol_u = dev._ol_u
?open_loop    ol_end = dev._ol_end
?special    special = dev.runner.special
?table    table = dev.opt.plant.load_table
    warn = False
    event = None
    stop = k + n
"""
_LOOP = """\
    for k in range(k + 1, stop + 1):
?ready&!w_is_u        w = u + $uoff
?ready&w_is_u        w = u
!ready        w = 0.0
?up        if w > $up:
?up            w = $up
?up        elif w < $nup:
?up            w = $nup
?load        wl = w - $load
!load        wl = w
?table2        if x <= $t_x0:
?table2            wl -= $t_y0
?table2        elif x <= $t_x1:
?table2            wl -= $t_y0 + $t_dy * (x - $t_x0) / $t_dx
?table2        else:
?table2            wl -= $t_y1
?table        wl -= _interp(table, x)
?search        x0 = x
?special        x, v = special(x, v, wl)
!special        if not $lo < x < $hi:
!special            x, v = dev.runner.special(x, v, wl)
!special        else:
!special&!fc0            if v > 0:
!special&!fc0                we = wl - $fc
!special&!fc0            elif v < 0:
!special&!fc0                we = wl + $fc
!special&!fc0            elif $nfc <= wl <= $fc:
!special&!fc0                we = None
!special&!fc0            else:
!special&!fc0                we = wl - $fc if wl > 0 else wl + $fc
!special&!fc0            if we is not None:
!special&!fc0                kw = $K * we
!special&fc0            if v != 0.0 or wl != 0.0:
!special&fc0                kw = $K * wl
!special&!phi1                v1 = $phi * v + kw * $g1
!special&phi1                v1 = v + kw * $g1
!special                if v * v1 < 0:
!special                    x, v = _step(x, v, wl, $K, $a, $fc, $T, dev.zoh)
!special                else:
!special                    x += v * $g1 + kw * $g2
!special                    v = v1
?search        if $hlo <= x0 < $hhi and floor((x - $ioff) / $iper) > floor((x0 - $ioff) / $iper):
?search            xi = floor((x - $ioff) / $iper) * $iper + $ioff
?search&ideal            event = ("home", xi - $enc0)
?search&!ideal            event = ("home", floor(xi) - $enc0)
?ideal        ap = x - $enc0
!ideal        ap = floor(x) - $enc0
?closed        if ntraj:
?closed            j = k - k0
?closed            cp = traj[j] if j < ntraj else traj[-1] + tail_v * (j - ntraj + 1)
?closed        elif tail_v:
?closed            cp += tail_v
?closed        fe = cp - ap
?closed        cv = cp - cpp
?closed&use_ca        ca = cv - cvp
?closed&int_always        if not clamped:
?closed&!int_always        if cv == 0 and not clamped:
?closed            ie += fe
?closed&ilim            ie = $ilim if ie > $ilim else ($nilim if ie < $nilim else ie)
?closed&use_av        av = ap - app
?closed        u = $law
?closed&!ff0        if cv > 0:
?closed&!ff0            u += $ff
?closed&!ff0        elif cv < 0:
?closed&!ff0            u -= $ff
?closed        clamped = True
?closed        if u > $lim:
?closed            u = $lim
?closed        elif u < $nlim:
?closed            u = $nlim
?closed        else:
?closed            clamped = False
?closed        cpp, cvp = cp, cv
?closed        afe = fe if fe >= 0 else -fe
?closed        if afe > fe_max:
?closed            fe_max = afe
?closed&check        if afe > $check:
?closed&check&warn_on            if afe > $warn_lim:
?closed&check&warn_on                warn = True
?closed&check&fatal_on            if afe > $fatal:
?closed&check&fatal_on                event = "fatal"
?closed&check&fatal_on                u = 0.0
?open_loop        cp = ap
?open_loop        u = ol_u
?open_loop        if ol_end and k >= ol_end:
?open_loop            event = "open loop end"
?killed        u = 0.0
?killed        cp = ap
?dac        u = $q * floor(u / $q)
        app = ap
?trace        rec((k, cp - origin, ap - origin, u))
?gather        gat((k, cp - origin, ap - origin, u, $cie * ie))
        if event is not None:
            break
"""
_STORE = """\
    dev.x_ = x
    dev.v_ = v
    dev.k = k
    dev._cp_ = cp
    dev._cpp_ = cpp
    dev._cvp_ = cvp
    dev._app_ = app
    dev._ie_ = ie
    dev._clamped_ = clamped
?closed&capture    dev._ca = ca
?closed&capture    dev._av = av
    dev.u_ = u
    dev.w_ = w
    dev.fe_ = fe
    dev.fe_max_ = fe_max
?closed&warn_on    warn = warn or (fe if fe >= 0 else -fe) > $warn_lim
!closed|!warn_on    warn = False
    dev.warn_ = warn
"""
_SOURCE = "def cycles(dev, n):\n" + _HEAD + _LOOP + _STORE + """\
    if event is not None:
        dev.runner.on_event(event)
    return stop - k
"""

# A whole scan of the device (ServoAxis.update) in its common cases, the loop closed and
# moving (rendered with the flags of that state only), or held at a fixed point of the
# loop (LoopRunner), or at rest where the runner would only run the cycles: FE != 0 with
# the integrator free and no DAC quantisation (no fixed point, the integrator moves; no
# creep, which needs the DAC's steps: LoopRunner.run). The update's checks, the cycles
# above, the status words (status.SOURCE) from the locals; at the fixed point the words
# of the last scan again, with the new servo cycle count. It reads and writes the state's
# fields (`x_`...): the properties over them drop these caches when anyone else assigns
# them (state.guard). It returns False, having done nothing, when the case does not hold
# (a command word changed, a fault, the drive's wired READY off or just back, a new value
# in the load mass word, an I-variable change waiting...); whatever is rarer after the
# cycles (an event, the end of a trajectory, a limit wired to the PMAC) goes to the
# device's own code.
_SCAN = """\
def scan(dev, t, dt):
    if dev._w[$ctl_i] != dev._ctl_prev or not dev.closed_ or dev.fault_ != "none" \\
            or dev.homing_ == 1 or dev._watch and not dev._ivars_clean():
        return False
?estop    if dev._i[$estop_idx]:  # (the drive's READY wired: amp_ready() inlined)
?estop        return False
?power    if not dev._q[$power_idx]:
?power        return False
?wired    if not dev._ready_:  # (READY back: the device's update takes it)
?wired        return False
?mass    if dev._mass_get($mass_word) != dev._mass_f:  # (a new load mass: the update's)
?mass        return False
    n = floor(round(t * 1e6) * $hz_us + 1e-9) - dev.k
    if n <= 0:
        return False
    if dev._fixed:  # at the fixed point, still since the last scan: only the count moves
        x = dev.x_
        if dev._creep or dev._active or x != dev._x_prev_scan \\
                or not $plim_lo < x < $plim_hi or not dt > 0:
            return False
?trace        dev.runner._repeat(n)
?trace        if len(dev.trace) >= $trim_at:
?trace            dev.runner.trim()
?trace        k = dev.k
!trace        k = dev.k = dev.k + n
        words = dev._rest_words  # the status words but TICKS, unchanged
        if words is None:  # (the first such scan: written in full, and kept)
            dev._finish(dt)
            dev._rest_words = bytes(dev._buf[$status_at:$status_end])
        else:
            buf = dev._buf
            buf[$status_at:$status_end] = words
            _pack_ticks(buf, $ticks_at, k & 0x7FFFFFFF)
        return True
?dac    if dev.v_ == 0.0:
?dac        return False
!dac    if dev.v_ == 0.0 and (dev.fe_ == 0.0 or dev._clamped_):
!dac        return False
""" + _HEAD + _LOOP + _STORE + """\
    if event is not None:
        dev.runner.on_event(event)
        n = stop - k
        while n > 0:
            n = dev._cycles(n)
?trace        if len(dev.trace) >= $trim_at:
?trace            dev.runner.trim()
        dev._finish(dt)
        return True
?trace    if len(dev.trace) >= $trim_at:
?trace        dev.runner.trim()
    slow = dev._st_slow  # (the bits no tick of this scan changed: status.SLOW)
    if not $plim_lo < x < $plim_hi or dev._active and not tail_v and k - k0 + 1 >= ntraj \\
            or slow < 0:
        dev._finish(dt)
        return True
    if dt > 0:
        vel = dev._vel_ = (x - dev._x_prev_scan) / dt
    else:
        vel = dev._vel_
    dev._x_prev_scan = x
    closed = True
    err = dev.error_
    origin = dev.origin_
    in_pos, lp, lm, cur_scale, buf, at = $in_pos, $lp, $lm, $cur_scale, dev._buf, $status_at
$status
    return True
"""


def _keep(tags: str, flags: dict[str, bool]) -> bool:
    """`a&!b`: a and not b; `a|b`: a or b (one operator per tag list)."""
    if "|" in tags:
        return any(_keep(t, flags) for t in tags.split("|"))
    for tag in tags.split("&"):
        want = not tag.startswith("!")
        if flags[tag.lstrip("!")] != want:
            return False
    return True


class Raw(str):
    """A value written into the source as it is (an expression), not as its repr."""

    def __repr__(self) -> str:
        return str(self)


def law(c: Any, off: float) -> tuple[Raw, bool]:
    """The law's expression (the coefficients `c` as literals, Ixx29 last) with the terms
    whose gain is 0 left out where that cannot change u (off is not -0.0), and whether u
    then never is -0.0 (so `u + 0.0` is u)."""
    no_neg_zero = not (off == 0 and math.copysign(1.0, off) < 0)
    terms = [(c.fe, "+", "fe"), (c.cv, "+", "cv"), (c.ca, "+", "ca"), (c.ie, "+", "ie"),
             (c.av, "-", "av")]
    kept = [t for t in terms if t[0] != 0.0 or not no_neg_zero] or [(0.0, "+", "fe")]
    expr = " ".join(f"{op} {g!r} * {v}" for g, op, v in kept)
    expr = expr[2:] if expr.startswith("+ ") else expr
    return Raw(f"{expr} + {off!r}"), no_neg_zero


def render(values: dict[str, Any], flags: dict[str, bool], source: str = _SOURCE) -> str:
    """The cycles function's source (or `scan_source`'s) for these constants and flags."""
    out = []
    for line in source.splitlines():
        if line[:1] in ("?", "!"):
            tags = line.split(" ", 1)[0]
            if not _keep(tags[1:] if tags[0] == "?" else tags, flags):
                continue
            line = line[len(tags):]  # the code keeps its indentation after the tag
        out.append(line)
    return Template("\n".join(out) + "\n").substitute(
        {k: repr(v) for k, v in values.items()})


def scan_source() -> str:
    """The scan template, the status words' description in it ($status)."""
    return _SCAN.replace("$status\n", status.indent(status.FAST + status.PACK))


# Generated functions kept, the oldest first out: an axis has a few cases (its flags) and
# renders them again after a snapshot's restore or a new load mass; a host that keeps
# writing new constants must not grow the process without bound.
RENDERED_ENTRIES = 128
_RENDERED: dict[tuple[Any, ...], Callable[..., Any]] = {}


def generated(values: dict[str, Any], flags: dict[str, bool], interp: Callable[..., float],
              step: Callable[..., Any], source: str = _SOURCE,
              name: str = "cycles") -> Callable[..., Any]:
    """`compile_cycles(render(values, flags, source), ...)`, the rendering skipped for
    constants and flags seen before (a rebuild after a snapshot's restore or a change of
    the mass renders the same source again: 0.5 ms a time). Keyed on the values' reprs,
    which is what the source holds (0.0 and -0.0 are equal keys otherwise)."""
    key = (source, name, tuple((k, repr(v)) for k, v in values.items()),
           tuple(flags.items()))
    fn = _RENDERED.get(key)
    if fn is None:
        if len(_RENDERED) >= RENDERED_ENTRIES:
            del _RENDERED[next(iter(_RENDERED))]
        fn = _RENDERED[key] = compile_cycles(render(values, flags, source), interp, step, name)
    return fn


def compile_cycles(source: str, interp: Callable[..., float], step: Callable[..., Any],
                   name: str = "cycles") -> Callable[..., Any]:
    """The function `name` of `source` (its code object from the shared cache of generated
    source, softplc.runtime.codecache)."""
    ns: dict[str, Any] = {**status.NAMESPACE, "floor": math.floor, "_interp": interp,
                          "_step": step, "inf": math.inf}
    exec(compile_code(source, "<servo loop>"), ns)  # noqa: S102 (our own template)
    return ns[name]
