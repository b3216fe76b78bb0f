"""`softplc plant up --netns` / `plant down`: each controller of a plant file as its own
`softplc run` daemon in its own network namespace, the Remote Link over TCP between them
(softplc.runtime.linktcp), the shared devices and wires as a host of their own (`plant
process`, softplc.plant.process: the wired I/O over TCP, softplc.runtime.wiretcp), a
namespace for a SCADA, and the plant page on this machine (issue 35).

The network, all of it inside namespaces made here (iproute2), but one veth:

    namespace spTAG-scada: bridge brTAG, address .254 (the SCADA's host)
      veth vTAGNb -- vTAGNa in namespace spTAG-NAME, the controller's address
      veth vTAGNb -- vTAGNa in namespace spTAG.plant, .252 (the plant host)
      veth vTAGrb -- vTAGr in this machine's namespace, .253 (the page, a browser)

TAG: 6 hex digits of the plant file's absolute path (two plants never share names; an
interface name stays within Linux's 15 characters). Addresses: each controller's `host`
from the plant file, else 10.35.0.N (N its place in the file); a /24 around them.
Each daemon: Modbus on port 502 of its address, a remote answers the link on `LINK_PORT`,
the plant host's wires on `WIRE_PORT`, the web monitor on `WEB_PORT` (tokens made here,
given in the environment). What `up` made (namespaces, the veth, processes, tokens) is
written to `spTAG.json` (owner only) in the state folder before it is made, which `down`
reads to remove it all; a process that dies leaves the others running (each is a process
of its own, in a session of its own).

Start-up: the imports every daemon needs are loaded once here (while `ip -batch` makes the
network), then each daemon, the plant host and the page are forks of this process that
enter their namespace (setns) and run their `softplc` command line: no Python start-up and
no imports per daemon. EXCH links reach the named controller's host as on a network.
"""

from __future__ import annotations

import atexit
import ctypes
import hashlib
import ipaddress
import json
import os
import runpy
import secrets
import shutil
import signal
import subprocess
import sys
import threading
import time
import tomllib
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from softplc.errors import PlantStateError

if TYPE_CHECKING:  # imported where used: `plant down` and a refused `plant up` need
    # neither the plant model nor the process (the configuration, pydantic: 0.5 s of CPU)
    from softplc.plant.model import PlantSpec

MODBUS_PORT = 502  # a real Twido's Modbus TCP port [Modbus TCP spec: port 502]
LINK_PORT = 5101  # where a remote answers the link (a softplc choice)
DEFAULT_NET = ipaddress.ip_network("10.35.0.0/24")  # private (RFC 1918), issue 35's number
SCADA_HOST = 254  # the SCADA's address in the /24
ROOT_HOST = 253  # this machine's own address on the plant network (the plant page, a browser)
PLANT_HOST = 252  # the plant host's (the shared devices and wires: `plant process`)
WEB_PORT = 8020  # each controller's web monitor, on its own address (softplc.web's default)
START_TIMEOUT_S = 30.0  # a daemon's banner must appear within this (a slow, loaded host)
BANNER_POLL_S = 0.02  # how often `up` looks at the logs for the banners
# the last banner line of `softplc run` (tools and tests wait for it) and `plant process`
PAGE_BANNER = "plant page: http://"  # the page's URL
BANNERS = ("Modbus TCP server listening on", "plant process: ticking", PAGE_BANNER)
PAGE = "page"  # the plant page's process in the record
PAGE_PORT = 8030  # the plant page's default port, on 127.0.0.1 (docs/plant.md)
PLANT = "plant"  # the plant host's name in the record; its namespace is spTAG.plant (a
# controller's name has no '.': never the same)
TOKEN_BYTES = 24  # the monitors' token (secrets.token_urlsafe)
NETNS_DIR = Path("/var/run/netns")  # where `ip netns add` keeps a namespace [ip-netns(8)]
CLONE_NEWNET = 0x40000000  # setns(2)'s namespace type [linux/sched.h]
STOP_TIMEOUT_S = 10.0


def tag(plant_file: Path) -> str:
    return hashlib.sha1(str(plant_file.resolve()).encode()).hexdigest()[:6]


def netns_works() -> str:
    """'' if network namespaces can be made here, else why not."""
    if shutil.which("ip") is None:
        return "no iproute2 'ip' command"
    if os.geteuid() != 0:
        return "not root (ip netns add needs CAP_SYS_ADMIN)"
    probe = f"spprobe{os.getpid()}"
    r = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if r.returncode:
        return f"ip netns add fails: {r.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return ""


def _ip_batch(lines: list[str], ns: str | None = None) -> None:
    """iproute2 commands, one `ip -batch` process (in namespace `ns`); the first that
    fails stops it and is reported."""
    cmd = ["ip", *(["-n", ns] if ns else []), "-batch", "-"]
    r = subprocess.run(cmd, input="\n".join(lines) + "\n", capture_output=True, text=True)
    if r.returncode:
        raise PlantStateError(f"{' '.join(cmd)}: {r.stderr.strip()}")


def addresses(spec: PlantSpec) -> dict[str, str]:
    """Each controller's address: its `host`, else the next of 10.35.0.N."""
    out = {}
    for i, (name, entry) in enumerate(spec.data.controllers.items(), start=1):
        out[name] = entry.host or str(DEFAULT_NET.network_address + i)
    return out


def _commands(spec: PlantSpec, hosts: dict[str, str], plant_host: str = "",
              web: bool = False) -> dict[str, list[str]]:
    """Each controller's `softplc run` command line: the link options from the plant, the
    wire options (its wired inputs, driven by `plant_host` only), its web monitor on its
    own address (`web`; its token from the environment) or none."""
    from softplc.plant.process import WIRE_PORT, wired_io

    io = wired_io(spec)
    masters = {e.master: e for e in spec.data.links.values() if e.type == "remote_link"}
    linked = {p for e in masters.values() for p in e.peers}
    out = {}
    for name in spec.data.controllers:
        program = spec.programs.get(name)
        if program is None:
            raise PlantStateError(f"{name}: a remote I/O controller has no program to run "
                                  "as a daemon; `plant up` runs program controllers")
        cmd = [sys.executable, "-m", "softplc", "run", str(program.resolve()), "--host",
               hosts[name], "--port", str(MODBUS_PORT), "--cold"]
        # the token travels in the environment (SOFTPLC_WEB_TOKEN), not on the command line
        cmd += ["--web", str(WEB_PORT), "--web-host", hosts[name]] if web else \
            ["--web", "off"]
        if name in io:
            ins, outs = io[name]
            cmd += ["--wire-listen", f"{hosts[name]}:{WIRE_PORT}", "--wire-peer", plant_host,
                    "--wire-in", ",".join(ins), "--wire-out", ",".join(outs)]
        config = spec.data.controllers[name].config
        if config is not None:
            path = (spec.file.parent / config).resolve()
            cmd += ["--config", str(path)]
        if name in masters or name in linked:
            if config is None or "remote_link" not in tomllib.loads(path.read_text()):
                raise PlantStateError(
                    f"{name}: `plant up` runs its configuration as it is: give it its "
                    f"[remote_link] section (the plant adds it only in one process)")
        if name in masters:
            for peer in masters[name].peers:
                addr = spec.data.controllers[peer].address
                cmd += ["--link-remote", f"{addr}={hosts[peer]}:{LINK_PORT}"]
        elif name in linked:
            cmd += ["--link-listen", f"{hosts[name]}:{LINK_PORT}"]
        out[name] = cmd
    return out


def record_path(plant_file: Path, state_dir: Path) -> Path:
    """Where `up` records plant `plant_file` in `state_dir` (`down` reads it)."""
    return state_dir / f"sp{tag(plant_file)}.json"


def not_up(plant_file: Path, state_dir: Path) -> Path:
    """The record file of a plant that is not up yet, else a clear error (before `up`
    loads anything)."""
    record_file = record_path(plant_file, state_dir)
    if record_file.exists():
        raise PlantStateError(f"{plant_file}: already up ({record_file}); `plant down` first")
    return record_file


def up(spec: PlantSpec, state_dir: Path, preload: Callable[[], Any],
       page_port: int | None = PAGE_PORT) -> dict[str, Any]:
    """Make the namespaces, start every daemon (and the plant host, when the plant has
    wires or shared devices) at once, wait for them all; the record of what was made.
    Each is a fork of this process running its `softplc` command line, once `preload`
    imported what they run. `page_port`: the plant page on 127.0.0.1
    of this machine (0: any free port) and each daemon's web monitor on its own address
    (tokens for them all); None: neither."""
    web = page_port is not None
    t = tag(spec.file)
    record_file = not_up(spec.file, state_dir)
    hosts = addresses(spec)
    net = ipaddress.ip_network(f"{next(iter(hosts.values()))}/24", strict=False)
    plant_host = str(net.network_address + PLANT_HOST)
    token = secrets.token_urlsafe(TOKEN_BYTES) if web else ""
    read_token = secrets.token_urlsafe(TOKEN_BYTES) if web else ""
    commands = _commands(spec, hosts, plant_host, web)
    physical = bool(spec.data.wires or spec.data.devices)
    state_dir.mkdir(mode=0o700, parents=True, exist_ok=True)
    scada = f"sp{t}-scada"
    record: dict[str, Any] = {"plant": str(spec.file.resolve()), "namespaces": [scada],
                              "scada": str(net.network_address + SCADA_HOST),
                              "root": str(net.network_address + ROOT_HOST),
                              "root_veth": f"v{t}r", "token": token,
                              "read_token": read_token, "page": "", "controllers": {},
                              "processes": {}}

    def keep() -> None:
        write_record(record_file, record)

    keep()  # before anything is made: `down` removes a half-made plant too
    # the imports the daemons share, while iproute2 makes the network (its own processes)
    loading = threading.Thread(target=preload, name="preload")
    loading.start()
    try:
        members = {f"sp{t}-{name}": hosts[name] for name in commands}
        if physical:
            members[f"sp{t}.{PLANT}"] = plant_host
        record["namespaces"] += list(members)
        if _root_has(net):  # see _network
            record["root"] = record["root_veth"] = ""
        keep()
        _network(t, net, record, members)
        loading.join()
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        daemon_env = dict(env, SOFTPLC_WEB_TOKEN=token, SOFTPLC_WEB_READ_TOKEN=read_token) \
            if web else env  # not on the command line (`ps`)
        for name, cmd in commands.items():  # every daemon at once; then wait for them all
            c = _start(f"sp{t}-{name}", cmd, state_dir / f"sp{t}-{name}.log", daemon_env)
            record["controllers"][name] = {**c, "host": hosts[name],
                                           "web_port": WEB_PORT if web else None}
            keep()
        if physical:
            cmd = [sys.executable, "-m", "softplc", "plant", "process", str(spec.file)]
            c = _start(f"sp{t}.{PLANT}", cmd, state_dir / f"sp{t}.{PLANT}.log", env)
            record["processes"][PLANT] = {**c, "host": plant_host}
            keep()
        if web and record["root"]:  # the page reaches the monitors through the root veth
            cmd = [sys.executable, "-m", "softplc", "plant", "page", str(spec.file),
                   "--record", str(record_file), "--port", str(page_port)]
            record["processes"][PAGE] = _start(None, cmd,
                                               state_dir / f"sp{t}.{PAGE}.log", env)
            keep()
        _wait_banners({**record["controllers"], **record["processes"]})
        if PAGE in record["processes"]:
            log = Path(record["processes"][PAGE]["log"]).read_text()
            record["page"] = "http://" + log.split(PAGE_BANNER, 1)[1].split()[0]
            keep()
    except BaseException:
        loading.join()
        down(record_file)
        raise
    return record


def write_record(path: Path, record: dict[str, Any]) -> None:
    """`up`'s record, written whole or not at all (a new file renamed over the old one):
    the plant page's process reads it while `up` goes on adding to it, and read a file
    truncated for rewriting ("Expecting value": the page did not start, issue 33)."""
    tmp = path.with_name(f".{path.name}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:  # owner only: it holds the monitors' token
        json.dump(record, f, indent=1)
    os.replace(tmp, path)


def _network(t: str, net: Any, record: dict[str, Any], members: dict[str, str]) -> None:
    """The SCADA namespace and its bridge, a namespace for each of `members` ({namespace:
    address}) joined to the bridge by a veth pair, and this machine's veth into the bridge
    (`record["root_veth"]`; none when this machine has an address in `net` already:
    another plant up in the same network, two routes to it would be a lottery). In 2 +
    len(members) `ip -batch` runs, not one `ip` process per step."""
    scada, bridge, n = record["namespaces"][0], f"br{t}", net.prefixlen
    root = [f"netns add {ns}" for ns in [scada, *members]]
    inside = [f"link add {bridge} type bridge",
              f"addr add {record['scada']}/{n} dev {bridge}",
              f"link set {bridge} up", "link set lo up"]
    if record["root_veth"]:
        v = record["root_veth"]
        root += [f"link add {v} type veth peer name {v}b netns {scada}",
                 f"addr add {record['root']}/{n} dev {v}", f"link set {v} up"]
        inside.append(f"link set {v}b master {bridge} up")
    for i, ns in enumerate(members):
        va, vb = f"v{t}{i}a", f"v{t}{i}b"
        root.append(f"link add {va} netns {ns} type veth peer name {vb} netns {scada}")
        inside.append(f"link set {vb} master {bridge} up")
    _ip_batch(root)
    _ip_batch(inside, scada)
    for i, (ns, addr) in enumerate(members.items()):
        va = f"v{t}{i}a"
        _ip_batch([f"addr add {addr}/{n} dev {va}", f"link set {va} up", "link set lo up"],
                  ns)


def _root_has(net: ipaddress.IPv4Network | ipaddress.IPv6Network) -> bool:
    """This machine (the root namespace) has an address in `net` already."""
    r = subprocess.run(["ip", "-o", "addr", "show", "to", str(net)], capture_output=True,
                       text=True)
    return bool(r.stdout.strip())


def _start(ns: str | None, cmd: list[str], log: Path, env: dict[str, str]) -> dict[str, Any]:
    """Start `softplc` command line `cmd` in namespace `ns` (None: this machine's own), in
    a session of its own, its output to `log`: a fork of this process (whose imports the
    child shares: no Python start-up and no imports per daemon) that enters the namespace
    and runs the command as `python -m softplc` does (softplc/__main__.py)."""
    argv = cmd[3:]  # [python, -m, softplc, ...]
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)  # the monitor's token
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the child: never returns

        def setup() -> None:
            os.setsid()
            os.dup2(fd, 1)
            os.dup2(fd, 2)
            os.close(fd)
            sys.stdout.reconfigure(line_buffering=True)  # type: ignore[union-attr]
            if ns is not None:
                _enter(ns)
            os.environ.clear()
            os.environ.update(env)

        run_forked(argv, setup)
    os.close(fd)
    return {"pid": pid, "namespace": ns, "log": str(log)}


def run_forked(argv: list[str], setup: Callable[[], None]) -> NoReturn:
    """In a forked child: `setup()` (its stdio, namespace, environment), then `softplc
    ARGV` run as `python -m softplc` runs it (softplc/__main__.py), and the process ended
    as an interpreter ends: sys.exit's status (a message printed, status 1), the
    non-daemon threads waited for, the atexit functions run, an uncaught Ctrl-C a
    traceback then death by SIGINT; anything else a traceback and status 1. The test
    suite's daemons start the same way (tests/zygote.py)."""
    rc = 1
    try:
        setup()
        sys.argv = ["softplc", *argv]
        try:
            runpy.run_module("softplc", run_name="__main__", alter_sys=True)
            rc = 0
        except SystemExit as e:
            if e.code is None or isinstance(e.code, int):
                rc = e.code or 0
            else:  # sys.exit("message"), as the interpreter prints it
                print(e.code, file=sys.stderr)
        except KeyboardInterrupt:
            traceback.print_exc()
            rc = -signal.SIGINT
        threading._shutdown()  # type: ignore[attr-defined]
        atexit._run_exitfuncs()
    except BaseException:
        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001 - a closed pipe: nothing more to say
                pass
        if rc < 0:
            signal.signal(-rc, signal.SIG_DFL)
            os.kill(os.getpid(), -rc)
        os._exit(rc & 0xFF)


def _enter(ns: str) -> None:
    """This process into network namespace `ns` (setns(2), as `ip netns exec` does)."""
    libc = ctypes.CDLL(None, use_errno=True)
    fd = os.open(NETNS_DIR / ns, os.O_RDONLY)
    try:
        if libc.setns(fd, CLONE_NEWNET):
            err = ctypes.get_errno()
            raise OSError(err, f"setns {ns}: {os.strerror(err)}")
    finally:
        os.close(fd)


def _wait_banners(started: dict[str, dict[str, Any]]) -> None:
    """Wait for every process' last banner line at once (they start in parallel)."""
    end = time.monotonic() + START_TIMEOUT_S
    waiting = dict(started)
    while waiting:
        for name, c in list(waiting.items()):
            text = Path(c["log"]).read_text()
            if any(b in text for b in BANNERS):
                del waiting[name]
                continue
            try:
                if os.waitpid(c["pid"], os.WNOHANG)[0]:
                    raise PlantStateError(f"{name} did not start: {text.strip()[-500:]}")
            except ChildProcessError:
                pass
        if waiting and time.monotonic() >= end:
            raise PlantStateError(f"{', '.join(waiting)}: no banner within "
                                  f"{START_TIMEOUT_S:g} s (logs: "
                                  f"{', '.join(c['log'] for c in waiting.values())})")
        time.sleep(BANNER_POLL_S)


def down(record_file: Path) -> list[str]:
    """Stop every process `up` started and remove every namespace and the veth it made;
    what was done."""
    if not record_file.exists():
        raise PlantStateError(f"{record_file}: no plant is up (nothing recorded)")
    record = json.loads(record_file.read_text())
    done = []
    stopping = {}
    for name, c in {**record.get("processes", {}), **record["controllers"]}.items():
        try:  # the session `up` gave it (the process alone if it has not made it yet)
            if not _alive(c["pid"]):
                raise ProcessLookupError
            try:
                os.killpg(c["pid"], signal.SIGTERM)
            except ProcessLookupError:
                os.kill(c["pid"], signal.SIGTERM)
        except ProcessLookupError:
            done.append(f"{name}: already gone")
            continue
        stopping[name] = c["pid"]
    end = time.monotonic() + STOP_TIMEOUT_S  # they all stop at once
    while time.monotonic() < end and any(_alive(p) for p in stopping.values()):
        time.sleep(BANNER_POLL_S)
    for name, pid in stopping.items():
        if _alive(pid):
            try:
                os.killpg(pid, signal.SIGKILL)
            except ProcessLookupError:
                os.kill(pid, signal.SIGKILL)
            done.append(f"{name}: killed (no stop within {STOP_TIMEOUT_S:g} s)")
        else:
            done.append(f"{name}: stopped")
    veth = record.get("root_veth")
    if veth:  # removed with its peer in the SCADA namespace; here if that was not made
        r = subprocess.run(["ip", "link", "del", veth], capture_output=True, text=True)
        done.append(f"veth {veth}: " + ("removed" if not r.returncode else "not there"))
    for ns in reversed(record["namespaces"]):
        r = subprocess.run(["ip", "netns", "del", ns], capture_output=True, text=True)
        done.append(f"namespace {ns}: " + ("removed" if not r.returncode else "not there"))
    record_file.unlink()
    return done


def _alive(pid: int) -> bool:
    try:
        if os.waitpid(pid, os.WNOHANG)[0]:  # our child (the tests): reaped
            return False
    except ChildProcessError:
        pass  # started by another `plant up` process
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie (dead, its new parent has not reaped it yet) is gone
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rpartition(")")[2].split()[0] != "Z"
