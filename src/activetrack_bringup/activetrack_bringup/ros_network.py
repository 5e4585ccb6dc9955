"""The DDS domain and discovery range a run uses, said out loud (``activetrack run`` prints it
before the graph starts, and ``summary.json`` keeps it), so that ROS tools can join the graph.

In one process the graph joins the caller's domain (``ROS_DOMAIN_ID``, default 0) with the
caller's discovery settings. With node processes, unless ``ROS_DOMAIN_ID`` is set, the run takes
a private domain (100 + pid % 100) so that concurrent runs never meet, and, when it starts every
node itself, discovery on this host only (``LOCALHOST``).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass

RMW_DEFAULT_DOMAIN = 0
RMW_DEFAULT_RANGE = "SUBNET"  # Jazzy's default when ROS_AUTOMATIC_DISCOVERY_RANGE is unset


@dataclass(frozen=True)
class RosNetwork:
    """Where a run's nodes talk: ``domain_id``, ``discovery_range`` (SUBNET, LOCALHOST, OFF or
    SYSTEM_DEFAULT), ``static_peers`` ('' for none), ``private``: the runner chose the domain
    (ROS_DOMAIN_ID unset)."""

    domain_id: int
    discovery_range: str
    static_peers: str = ""
    private: bool = False

    def describe(self) -> str:
        """One line: the domain, the range and how a tool joins them."""
        where = f"domain {self.domain_id}"
        if self.private:
            where += " (private to this run: ROS_DOMAIN_ID is unset)"
        peers = f", static peers {self.static_peers}" if self.static_peers else ""
        join = f"ROS_DOMAIN_ID={self.domain_id}"
        if self.discovery_range != RMW_DEFAULT_RANGE:
            join += f" ROS_AUTOMATIC_DISCOVERY_RANGE={self.discovery_range}"
        return (
            f"{where}, discovery {self.discovery_range}{peers}; tools join with {join} "
            f"(activetrack ros ... --domain {self.domain_id})"
        )

    def to_json(self) -> dict:
        return asdict(self)


def _env(name: str) -> str:
    return os.environ.get(name, "").strip()


def ros_network(processes: bool, every_node_here: bool = True) -> RosNetwork:
    """The network of a run in one process (``processes`` False) or with node processes
    (``every_node_here``: the runner starts all of them, so discovery stays on this host)."""
    peers = _env("ROS_STATIC_PEERS")
    given_range = _env("ROS_AUTOMATIC_DISCOVERY_RANGE").upper() or RMW_DEFAULT_RANGE
    given_domain = _env("ROS_DOMAIN_ID")
    if not processes:
        domain = int(given_domain) if given_domain else RMW_DEFAULT_DOMAIN
        return RosNetwork(domain, given_range, peers)
    domain = int(given_domain) if given_domain else 100 + os.getpid() % 100
    discovery = "LOCALHOST" if every_node_here else given_range
    return RosNetwork(domain, discovery, peers, private=not given_domain)
