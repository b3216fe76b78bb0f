"""`softplc plant up --netns` / `plant down`: each controller of a plant file as its own
`softplc run` daemon in its own network namespace, the Remote Link over TCP between them
(softplc.runtime.linktcp), plus a namespace for a SCADA (issue 35).

The network, all of it inside namespaces made here (iproute2):

    namespace spTAG-scada: bridge brTAG, address .254 (the SCADA's host)
      veth vTAGNb -- vTAGNa in namespace spTAG-NAME, the controller's address

TAG: 6 hex digits of the plant file's absolute path (two plants never share names; an
interface name stays within Linux's 15 characters). Addresses: each controller's `host`
from the plant file, else 10.35.0.N (N its place in the file); a /24 around them.
Each daemon: Modbus on port 502 of its address, a remote answers the link on `LINK_PORT`.
What `up` made (namespaces, processes) is written to `spTAG.json` in the state folder,
which `down` reads to remove it all; a daemon that dies leaves the others running (each is
a process of its own, in a session of its own).

Not carried between hosts: wires and shared devices (they are one process' objects: `plant
run`); EXCH links reach the named controller's host as they do on a network.
"""

from __future__ import annotations

import hashlib
import ipaddress
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

from softplc.errors import PlantStateError
from softplc.plant.model import PlantSpec

MODBUS_PORT = 502  # a real Twido's Modbus TCP port [Modbus TCP spec: port 502]
LINK_PORT = 5101  # where a remote answers the link (a softplc choice)
DEFAULT_NET = ipaddress.ip_network("10.35.0.0/24")  # private (RFC 1918), issue 35's number
SCADA_HOST = 254  # the SCADA's address in the /24
START_TIMEOUT_S = 30.0  # a daemon's banner must appear within this (a slow, loaded host)
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


def _ip(*args: str, ns: str | None = None) -> None:
    cmd = ["ip", *(["-n", ns] if ns else []), *args]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode:
        raise PlantStateError(f"{' '.join(cmd)}: {r.stderr.strip()}")


def addresses(spec: PlantSpec) -> dict[str, str]:
    """Each controller's address: its `host`, else the next of 10.35.0.N."""
    out = {}
    for i, (name, entry) in enumerate(spec.data.controllers.items(), start=1):
        out[name] = entry.host or str(DEFAULT_NET.network_address + i)
    return out


def _commands(spec: PlantSpec, hosts: dict[str, str]) -> dict[str, list[str]]:
    """Each controller's `softplc run` command line (the link options from the plant)."""
    masters = {e.master: e for e in spec.data.links.values() if e.type == "remote_link"}
    linked = {p for e in masters.values() for p in e.peers}
    out = {}
    for name in spec.data.controllers:
        program = spec.programs.get(name)
        if program is None:
            raise PlantStateError(f"{name}: a remote I/O controller has no program to run "
                                  "as a daemon; `plant up` runs program controllers")
        cmd = [sys.executable, "-m", "softplc", "run", str(program.resolve()), "--host",
               hosts[name], "--port", str(MODBUS_PORT), "--web", "off", "--cold"]
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


def up(spec: PlantSpec, state_dir: Path) -> dict[str, Any]:
    """Make the namespaces and start every daemon; the record of what was made."""
    t = tag(spec.file)
    record_file = state_dir / f"sp{t}.json"
    if record_file.exists():
        raise PlantStateError(f"{spec.file}: already up ({record_file}); `plant down` first")
    hosts = addresses(spec)
    commands = _commands(spec, hosts)
    state_dir.mkdir(parents=True, exist_ok=True)
    scada = f"sp{t}-scada"
    record: dict[str, Any] = {"plant": str(spec.file.resolve()), "namespaces": [scada],
                              "scada": "", "controllers": {}}

    def keep() -> None:
        record_file.write_text(json.dumps(record, indent=1))

    keep()  # before anything is made: `down` removes a half-made plant too
    try:
        net = ipaddress.ip_network(f"{next(iter(hosts.values()))}/24", strict=False)
        record["scada"] = str(net.network_address + SCADA_HOST)
        _ip("netns", "add", scada)
        bridge = f"br{t}"
        _ip("link", "add", bridge, "type", "bridge", ns=scada)
        _ip("addr", "add", f"{record['scada']}/{net.prefixlen}", "dev", bridge, ns=scada)
        _ip("link", "set", bridge, "up", ns=scada)
        _ip("link", "set", "lo", "up", ns=scada)
        for i, name in enumerate(commands):
            ns = f"sp{t}-{name}"
            record["namespaces"].append(ns)
            keep()
            _ip("netns", "add", ns)
            a, b = f"v{t}{i}a", f"v{t}{i}b"
            _ip("link", "add", a, "netns", ns, "type", "veth", "peer", "name", b,
                "netns", scada)
            _ip("link", "set", b, "master", bridge, "up", ns=scada)
            _ip("addr", "add", f"{hosts[name]}/{net.prefixlen}", "dev", a, ns=ns)
            _ip("link", "set", a, "up", ns=ns)
            _ip("link", "set", "lo", "up", ns=ns)
        for name, cmd in commands.items():
            ns = f"sp{t}-{name}"
            log = state_dir / f"sp{t}-{name}.log"
            with open(log, "w") as out:
                proc = subprocess.Popen(["ip", "netns", "exec", ns, *cmd], stdout=out,
                                        stderr=subprocess.STDOUT, start_new_session=True,
                                        env=dict(os.environ, PYTHONUNBUFFERED="1"))
            record["controllers"][name] = {"pid": proc.pid, "namespace": ns,
                                           "host": hosts[name], "log": str(log)}
            keep()
        for name, c in record["controllers"].items():
            _wait_banner(name, Path(c["log"]), c["pid"])
    except BaseException:
        down(record_file)
        raise
    return record


def _wait_banner(name: str, log: Path, pid: int) -> None:
    end = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < end:
        text = log.read_text()
        if "Modbus TCP server listening on" in text:
            return
        try:
            if os.waitpid(pid, os.WNOHANG)[0]:
                raise PlantStateError(f"{name} did not start: {text.strip()[-500:]}")
        except ChildProcessError:
            pass
        time.sleep(0.05)
    raise PlantStateError(f"{name}: no banner within {START_TIMEOUT_S:g} s ({log})")


def down(record_file: Path) -> list[str]:
    """Stop every daemon `up` started and remove every namespace it made; what was done."""
    if not record_file.exists():
        raise PlantStateError(f"{record_file}: no plant is up (nothing recorded)")
    record = json.loads(record_file.read_text())
    done = []
    for name, c in record["controllers"].items():
        pid = c["pid"]
        try:  # the session `up` gave it: `ip netns exec` and the daemon under it
            os.killpg(pid, signal.SIGTERM)
        except ProcessLookupError:
            done.append(f"{name}: already gone")
            continue
        end = time.monotonic() + STOP_TIMEOUT_S
        while time.monotonic() < end and _alive(pid):
            time.sleep(0.05)
        if _alive(pid):
            os.killpg(pid, signal.SIGKILL)
        done.append(f"{name}: stopped")
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
    return True
