"""A local Ray started by dsage_ray listens on 127.0.0.1 only, and every ``ray.init`` goes through one function."""

from __future__ import annotations

import ipaddress
import os
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def descendants(pid: int) -> set[int]:
    """``pid`` and every process below it (Ray's GCS and raylet are the driver's children, workers the raylet's)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # a process that ended while listed
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, todo = set(), [pid]
    while todo:
        current = todo.pop()
        found.add(current)
        todo += children.get(current, [])
    return found


def listening_addresses(pids: set[int]) -> dict[str, list[int]]:
    """``{address: [pid, ...]}`` of the TCP sockets in LISTEN state that ``pids`` hold (from /proc)."""
    owners: dict[str, list[int]] = {}
    for pid in pids:
        try:
            links = [os.readlink(fd) for fd in Path(f"/proc/{pid}/fd").iterdir()]
        except OSError:
            continue
        for link in links:
            if match := re.fullmatch(r"socket:\[(\d+)\]", link):
                owners.setdefault(match.group(1), []).append(pid)
    listening: dict[str, list[int]] = {}
    for table, width in (("tcp", 4), ("tcp6", 16)):
        for line in Path(f"/proc/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            local, state, inode = fields[1], fields[3], fields[9]
            if state != "0A" or inode not in owners:  # 0A: LISTEN
                continue
            raw = bytes.fromhex(local.split(":")[0])
            # /proc prints each 32-bit word in host (little-endian) order.
            address = ipaddress.ip_address(b"".join(raw[i:i + 4][::-1] for i in range(0, width, 4)))
            listening.setdefault(str(address), []).extend(owners[inode])
    return listening


def is_loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    return ip.is_loopback or (ip.version == 6 and ip.ipv4_mapped is not None and ip.ipv4_mapped.is_loopback)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads Linux's /proc")
def test_a_local_cluster_listens_on_the_loopback_address_only(ray_session):
    ray = ray_session

    @ray.remote
    def node_address() -> str:
        return ray.util.get_node_ip_address()

    assert ray.get(node_address.remote()) == "127.0.0.1"  # a worker has started and knows its node
    listening = listening_addresses(descendants(os.getpid()))
    assert listening, "found no listening socket of Ray's processes (the check would pass vacuously)"
    exposed = {address: pids for address, pids in listening.items() if not is_loopback(address)}
    assert not exposed, f"Ray listens beyond this machine: {exposed}"


def test_a_later_join_of_a_remote_cluster_announces_a_reachable_address():
    from ray._private import ray_constants

    from dsage_ray.ray import session

    before = (ray_constants.ENABLE_RAY_CLUSTER, os.environ.get("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"))
    with session._loopback_only():
        assert ray_constants.ENABLE_RAY_CLUSTER is False
    assert (ray_constants.ENABLE_RAY_CLUSTER, os.environ.get("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER")) == before


def test_every_ray_init_of_the_package_and_its_scripts_goes_through_start_ray():
    calls = [f"{path.relative_to(ROOT)}:{number}"
             for folder in ("dsage_ray", "experiments", "benchmarks", "examples")
             for path in (ROOT / folder).rglob("*.py")
             for number, line in enumerate(path.read_text().splitlines(), 1)
             if re.search(r"\bray\.init\(", line.split("#")[0])]
    assert calls and {call.split(":")[0] for call in calls} == {"dsage_ray/ray/session.py"}, calls
