"""The client's side of the protocol: one short-lived Zenoh client session and typed requests."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from fleet.errors import BadRequest, ControlError, RouterSilent
from fleet.wire import protocol as p
from fleet.wire.session import config_file, default_endpoint, open_client

if TYPE_CHECKING:
    import zenoh

STATUS_TIMEOUT = 3.0
APPLY_TIMEOUT = 10.0
# How long a status query waits, once its first STATUS_TIMEOUT passed without the router's own
# answer: while the router closes the link of an agent whose cable was pulled, it answers nothing
# for up to 10 s (measured on tests/multihost's three computers: 10.4 s; its log falls silent for
# 10.03 s from the close, which matches the 10 s SO_LINGER zenoh-link-tcp sets: a close with
# unsent data on a dead link waits that long).
ROUTER_STALL = 12.0
# Opening a session waits as long for the same reason (Zenoh's default: 10 s, which such a stall
# reached: 9.3 s measured), and says so once it has waited OPEN_NOTE_AFTER.
OPEN_TIMEOUT_MS = 15_000
OPEN_NOTE_AFTER = 2.0


def connect(
    endpoint: str | None = None, zenoh_config: Path | None = None, on_wait: Callable[[str], None] | None = None
) -> ControlClient:
    """A client of the router at `endpoint` (default: $FLEET_CONNECT or the local one), with the
    Zenoh config file given or named by $FLEET_ZENOH_CONFIG."""
    return ControlClient([default_endpoint() if endpoint is None else endpoint], config_file(zenoh_config), on_wait)


def _open_session(
    connect: list[str], zenoh_config: Path | None, on_wait: Callable[[str], None] | None
) -> zenoh.Session:
    """A client session, waiting up to OPEN_TIMEOUT_MS; `on_wait` is told once it has waited
    OPEN_NOTE_AFTER (Zenoh's open blocks, so a timer thread says it)."""
    note = None
    if on_wait is not None:
        note = threading.Timer(
            OPEN_NOTE_AFTER,
            on_wait,
            [
                f"the fleet router at {', '.join(connect)} has not taken the connection in {OPEN_NOTE_AFTER:.0f} s "
                f"(closing the link of an agent that just went away?); waiting up to {OPEN_TIMEOUT_MS / 1000:.0f} s"
            ],
        )
        note.daemon = True
        note.start()
    try:
        return open_client(connect, zenoh_config, settings={"transport/unicast/open_timeout": OPEN_TIMEOUT_MS})
    finally:
        if note is not None:
            note.cancel()


class ControlClient:
    def __init__(
        self, connect: list[str], zenoh_config: Path | None = None, on_wait: Callable[[str], None] | None = None
    ):
        """`on_wait`: told, in a line, when the client waits longer than usual (a command's stderr)."""
        self.connect = connect
        self.zenoh_config = zenoh_config
        self.on_wait = on_wait
        self.session = _open_session(connect, zenoh_config, on_wait)

    def close(self) -> None:
        self.session.close()

    def __enter__(self) -> ControlClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- status ---------------------------------------------------------------------------------

    def status(
        self, fleet: str | None = None, timeout: float = STATUS_TIMEOUT
    ) -> tuple[list[p.StatusReply], list[p.RegistryReply]]:
        """One wildcard get: a reply from every agent (per fleet it serves) and from the registry.
        ControlError when the router's registry does not answer: its access rules deny this client
        (an agent's certificate, say), and what agents answered would be a partial picture."""
        statuses, registries, timed_out = self._status_replies(p.status_query(fleet), timeout)
        if not registries and timed_out:  # the router itself is late, not denying: see ROUTER_STALL
            if self.on_wait is not None:
                self.on_wait(
                    f"the fleet router has not answered for {timeout:.0f} s (closing the link of an agent "
                    f"that just went away?); waiting up to {ROUTER_STALL:.0f} s more"
                )
            statuses, registries, timed_out = self._status_replies(p.status_query(fleet), ROUTER_STALL)
        # A router that holds no fleet answers the wildcard with nothing, but any fleet by name.
        if not registries and (fleet is not None or not self._status_replies(p.registry_key(p.NO_FLEET), timeout)[1]):
            if timed_out:  # asking again would wait as long: say so to the caller (RouterSilent)
                raise RouterSilent(
                    f"the fleet router did not answer the status query in {timeout + ROUTER_STALL:.0f} s "
                    "(still starting, or overloaded? see its log)"
                )
            config = f": {self.zenoh_config}" if self.zenoh_config else ""
            raise ControlError(
                "the fleet router did not answer the status query (still starting? or access denied: the Zenoh "
                f"config in use may be an agent's, not an operator's{config})"
            )
        return statuses, registries

    def _status_replies(self, key: str, timeout: float) -> tuple[list[p.StatusReply], list[p.RegistryReply], bool]:
        """The agents' and the registry's replies, and whether the query timed out (someone it
        reached did not answer) rather than ended (all answered, or the router denied it)."""
        statuses: list[p.StatusReply] = []
        registries: list[p.RegistryReply] = []
        answers, timed_out = self._answers(key, timeout)
        for answer in answers:
            try:
                data = p.parse(answer)
                if data.get("kind") == "status":
                    statuses.append(p.validate(data, p.StatusReply))
                elif data.get("kind") == "registry":
                    registries.append(p.validate(data, p.RegistryReply))
            except p.ProtocolError:
                continue  # another version of fleet on the same router: skip, don't crash
        return statuses, registries, timed_out

    def desired_states(self, fleet: str, timeout: float = STATUS_TIMEOUT) -> list[p.ApplyRequest]:
        """The desired state the router keeps for each agent of `fleet`: what the last deploy sent."""
        states = []
        for answer in self._answers(p.desired_key(fleet, "*"), timeout, p.encode(p.DesiredQuery()))[0]:
            try:
                states.append(p.decode(answer, p.ApplyRequest))
            except p.ProtocolError:
                continue  # another version of fleet on the same router: skip, don't crash
        return states

    def _answers(self, key: str, timeout: float, payload: bytes | None = None) -> tuple[list[bytes], bool]:
        """One wildcard get: the payload of every reply that is not an error, and whether it timed
        out (Zenoh ends a get that outlived its timeout with an error reply saying so)."""
        import zenoh

        replies = self.session.get(
            key,
            payload=payload,
            target=zenoh.QueryTarget.ALL,
            consolidation=zenoh.ConsolidationMode.NONE,
            timeout=timeout,
        )
        answers, timed_out = [], False
        for reply in replies:
            if reply.ok is not None:
                answers.append(reply.ok.payload.to_bytes())
            elif reply.err is not None and reply.err.payload.to_bytes() == b"Timeout":
                timed_out = True
        return answers, timed_out

    # -- requests to one agent ------------------------------------------------------------------

    def send_applies(
        self, requests: list[p.ApplyRequest], timeout: float = APPLY_TIMEOUT
    ) -> dict[str, p.ApplyReply | ControlError]:
        """Send every apply at once, then collect: agent -> ApplyReply | ControlError."""
        pending = []
        for request in requests:
            handler = self.session.get(
                p.apply_key(request.fleet, request.agent), payload=p.encode(request), timeout=timeout
            )
            pending.append((request.agent, handler))
        results: dict[str, p.ApplyReply | ControlError] = {}
        for agent, handler in pending:
            try:
                results[agent] = _one_reply(handler, p.ApplyReply, f"agent {agent}")
            except BadRequest as error:  # the spec was checked here: the agent's refusal is shown as its own
                results[agent] = ControlError(f"agent {agent} refused the request: {error}")
            except ControlError as error:
                results[agent] = error
        return results

    def request(
        self, key: str, message: p.Message, model: type[p.MessageT], what: str, timeout: float = 20.0
    ) -> p.MessageT:
        handler = self.session.get(key, payload=p.encode(message), timeout=timeout)
        return _one_reply(handler, model, what)

    def logs(self, agent: str, request: p.LogsRequest, timeout: float = 20.0) -> p.LogsReply:
        return self.request(p.logs_key(request.fleet, agent), request, p.LogsReply, f"agent {agent}", timeout)

    def param(self, agent: str, request: p.ParamRequest) -> p.ParamReply:
        """Get or set a node's parameter through its agent: the agent's own wait, plus the round trip."""
        return self.request(
            p.param_key(request.fleet, agent), request, p.ParamReply, f"agent {agent}", p.PARAM_TIMEOUT + 5
        )

    def restart(self, agent: str, request: p.RestartRequest) -> p.RestartReply:
        return self.request(p.restart_key(request.fleet, agent), request, p.RestartReply, f"agent {agent}")

    def world(self, fleet: str, agent: str, timeout: float = STATUS_TIMEOUT) -> p.WorldReply:
        """The full world state (trails, lidar hits, obstacles) from the agent running it."""
        return self.request(
            p.world_key(fleet, agent), p.WorldRequest(fleet=fleet), p.WorldReply, f"agent {agent}", timeout=timeout
        )

    def put_plan(self, plan: p.PlanRecord) -> None:
        self._put(p.plan_key(plan.fleet), p.encode(plan))

    def put_desired(self, requests: list[p.ApplyRequest]) -> None:
        """Leave each agent's desired state with the router: an agent that was away fetches it."""
        for request in requests:
            self._put(p.desired_key(request.fleet, request.agent), p.encode(request))

    def _put(self, key: str, payload: bytes) -> None:
        """A put the router must get.  Zenoh's default for a put is to drop it when the session's
        send queue is still full a millisecond later: a deploy's desired states (tens of KiB each)
        filled it, the plan put right after them was dropped about one deploy in five on a busy
        machine, and the deploy then waited for a plan the router never had until its timeout."""
        import zenoh

        self.session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)


def _one_reply(handler: Iterable[zenoh.Reply], model: type[p.MessageT], what: str) -> p.MessageT:
    for reply in handler:
        if reply.ok is not None:
            try:
                return p.decode(reply.ok.payload.to_bytes(), model)
            except p.ProtocolError as error:
                raise ControlError(f"{what} answered: {error}") from None
        failure = reply.err
        assert failure is not None  # a reply without a sample carries an error
        raw = failure.payload.to_bytes()
        try:
            refusal = p.decode(raw, p.ErrorReply)
        except p.ProtocolError:
            raise ControlError(f"{what}: {raw.decode('utf-8', 'replace')}") from None
        if refusal.code in p.INPUT_ERRORS:
            raise BadRequest(refusal.error)  # "robot robot2 has no node 'nosuch'": about the input, not the agent
        raise ControlError(f"{what} refused the request: {refusal.error}")
    raise ControlError(f"{what} is unreachable (not connected to the router, or it timed out)")
